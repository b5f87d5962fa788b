"""Pairwise statistics the GP kernels are functions of: squared distances, inner products.

:func:`difference_squared_distances` subtracts row pairs (memory ``N·M·D``; exact, for
one point against many and where a gradient must stay finite at coincident points).
The two others are the norm expansion ``|a|² + |b|² − 2 a·b`` (one
matrix product) clipped at zero:

- :func:`squared_distances` first shifts both sets by the mean of ``B`` (the expansion
  loses digits far from the origin) and gives a set's distances to itself an exact zero
  diagonal — the GPR's (:mod:`rigmap.regression.gpr`), whose inputs are raw features;
- :func:`expanded_squared_distances` is the plain expansion, on numpy arrays or torch
  tensors (the GPLVM differentiates through it) — the edits' GP, moving least squares
  and the GPLVM, whose inputs are already centred and scaled. Giving them the centred
  version would move their fitted hyper-parameters at round-off level (an optimiser's
  path through them), so each keeps the computation its numbers were made with.
"""

from __future__ import annotations

import numpy as np


def squared_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``||a - b||^2`` for all row pairs via the norm expansion (one matrix product).

    The expansion ``|a|^2 + |b|^2 - 2 a.b`` loses digits when the rows sit far
    from the origin, so both sets are first shifted by the mean of ``B``
    (distances do not change). What round-off remains can make near-identical
    rows slightly negative; those are clipped to zero so square roots stay
    real, and a set's distances to itself have an exact zero diagonal.
    """
    same = A is B
    A = np.asarray(A, dtype=np.float64)
    B = A if same else np.asarray(B, dtype=np.float64)
    centre = B.mean(axis=0)
    A = A - centre
    B = A if same else B - centre
    D2 = A @ B.T
    D2 *= -2.0
    D2 += np.einsum("ij,ij->i", A, A)[:, None]
    D2 += np.einsum("ij,ij->i", B, B)[None, :]
    np.maximum(D2, 0.0, out=D2)
    if same:
        np.fill_diagonal(D2, 0.0)
    return D2


def expanded_squared_distances(A, B):
    """``||a - b||^2`` for all row pairs of ``(N, D)`` and ``(M, D)`` numpy arrays or torch
    tensors (differentiable), by the plain norm expansion clipped at zero (no centring)."""
    d2 = (A * A).sum(1)[:, None] + (B * B).sum(1)[None, :] - 2.0 * A @ B.T
    return np.maximum(d2, 0.0) if isinstance(d2, np.ndarray) else d2.clamp_min(0.0)


def difference_squared_distances(A, B):
    """``||a - b||^2`` for all row pairs by differences, numpy or torch: ``(N, M, D)``
    memory, but no cancellation and a gradient that stays finite at coincident points
    (the GPLVM's connectivity prior; one row against many in the particle's field)."""
    return ((A[:, None, :] - B[None, :, :]) ** 2).sum(-1)


def inner_products(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``a.b`` for all row pairs (the dot-product kernels' statistic)."""
    return np.asarray(A, dtype=np.float64) @ np.asarray(B, dtype=np.float64).T
