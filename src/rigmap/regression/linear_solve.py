"""The regularised solve of Eq. 6, ``(K + theta1 I)^-1 Y``, for indefinite kernels too.

The multiquadric Gram matrix is indefinite, so every solve is an LU
factorisation, with a least-squares fallback when the matrix is numerically
singular — never Cholesky.
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

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
