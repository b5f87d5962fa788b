"""The GPs' factorisations and solves: LU for indefinite kernels, Cholesky for the rest.

- :func:`solve_regularized` — Eq. 6 of the GPR paper, ``(K + theta1 I)^-1 Y``. The
  multiquadric Gram matrix is indefinite, so it is an LU factorisation with a
  least-squares fallback when the matrix is numerically singular — never Cholesky.
- :func:`add_noise`, :func:`cholesky`, :func:`cholesky_solve`, :func:`solve_lower`,
  :func:`solve_lower_transposed` — positive definite kernels (the RBF with noise of the
  edits' GP and the GPLVM), on numpy arrays or torch tensors. The jitter policy is one
  rule: a model adds its noise variance plus a fixed jitter to the diagonal before
  factoring (:data:`JITTER` for the edits' GP, whose noise may fit to ~0; none for the
  GPLVM, whose noise has a floor of its own), never a retry with growing jitter.

Numpy Cholesky factors are SciPy's ``cho_factor`` layout: the lower triangle holds the
factor and the upper whatever LAPACK left there (``potrs``/``trsm`` never read it).
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import scipy.linalg
from scipy.linalg import cho_factor, cho_solve, lapack, solve_triangular

# Ours: the smallest diagonal jitter of a positive definite kernel (the edits' GP: its
# noise variance may fit to ~0 on noiseless procedural edits).
JITTER = 1e-10

# LU solutions with a reciprocal condition number below this are not trusted.
_MIN_RCOND = 1e-13


class Solution(NamedTuple):
    """Weights of Eq. 6, the solver that produced them and the LU's reciprocal condition."""

    weights: np.ndarray
    solver: str
    rcond: float


def solve_regularized(K: np.ndarray, Y: np.ndarray, regularization: float) -> Solution:
    """``(K + theta1 I)^-1 Y`` by LU; least squares when LU is numerically singular.

    With an indefinite kernel (multiquadric) ``+ theta1 I`` can also move a
    negative eigenvalue of ``K`` *onto* zero; the condition estimate catches
    that as well as plain rank deficiency.
    """
    A = K + regularization * np.eye(len(K))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
        with np.errstate(all="ignore"):
            lu, pivots = scipy.linalg.lu_factor(A, check_finite=False)
            rcond, _ = lapack.dgecon(lu, float(np.abs(A).sum(axis=0).max()), norm="1")
            rcond = float(rcond) if np.isfinite(rcond) else 0.0
            if rcond > _MIN_RCOND:
                W = scipy.linalg.lu_solve((lu, pivots), Y, check_finite=False)
                if np.isfinite(W).all():
                    return Solution(W, "lu", rcond)
    W = scipy.linalg.lstsq(A, Y, cond=1e-12, check_finite=False)[0]
    return Solution(W, "lstsq", rcond)


def _is_torch(x) -> bool:
    return type(x).__module__.startswith("torch")


def add_noise(K, noise_variance, jitter: float = 0.0):
    """``K + (noise_variance + jitter) I``: in place for a numpy array (returned), a new
    tensor for torch (autograd keeps both terms)."""
    if _is_torch(K):
        import torch

        return K + (noise_variance + jitter) * torch.eye(len(K), dtype=K.dtype)
    K[np.diag_indices_from(K)] += noise_variance + jitter
    return K


def cholesky(K):
    """The lower Cholesky factor ``L`` of a positive definite ``K`` (numpy: SciPy's
    ``cho_factor`` array, raising ``LinAlgError`` when ``K`` is not positive definite)."""
    if _is_torch(K):
        import torch

        return torch.linalg.cholesky(K)
    return cho_factor(K, lower=True)[0]


def cholesky_solve(L, B):
    """``K⁻¹ B`` from ``K``'s lower Cholesky factor (two triangular solves)."""
    if _is_torch(L):
        import torch

        return torch.cholesky_solve(B, L)
    return cho_solve((L, True), B)


def solve_lower(L, B):
    """``L⁻¹ B`` for a lower-triangular ``L`` (half a Cholesky solve: variances, priors)."""
    if _is_torch(L):
        import torch

        return torch.linalg.solve_triangular(L, B, upper=False)
    return solve_triangular(L, B, lower=True)


def solve_lower_transposed(L, B: np.ndarray) -> np.ndarray:
    """``L⁻ᵀ B`` (numpy): the second half of a Cholesky solve, when the first is kept."""
    return solve_triangular(L.T, B, lower=False)


def log_det(L):
    """``ln |K|`` from its lower Cholesky factor: ``2 Σ ln L_ii``."""
    if _is_torch(L):
        import torch

        return 2.0 * torch.log(torch.diagonal(L)).sum()
    return 2.0 * np.log(np.diag(L)).sum()
