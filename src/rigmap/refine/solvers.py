"""The solver a refinement asks for by name: ``cholesky``, ``block_cholesky`` or ``svd``.

A module of its own so that :mod:`rigmap.refine.block_cholesky`, built on the normal
equations' steps, and :mod:`rigmap.refine.normal_equations` need not import each other.
"""

from __future__ import annotations

import numpy as np

from rigmap.refine.block_cholesky import BlockCholeskyStep
from rigmap.refine.normal_equations import SOLVERS, CholeskyStep, Damping, SVDStep


def damped_solver(
    J: np.ndarray, damping: Damping, solver: str = "cholesky", scale: np.ndarray | None = None
):
    """A solver for the frames of ``J`` ``(F, R, C)``: ``.solve(residual (F, R)) -> (F, C)``.

    ``scale`` ``(C,)`` (optional) multiplies ``J``'s columns first: ``J·diag(scale)``.
    """
    if scale is not None and solver != "block_cholesky":
        J = J * scale
    if solver == "cholesky":
        return CholeskyStep(J, damping)
    if solver == "svd":
        return SVDStep(J, damping)
    if solver == "block_cholesky":
        return BlockCholeskyStep(J, damping, scale)
    raise ValueError(f"refine solver: expected one of {SOLVERS}, got {solver!r}")
