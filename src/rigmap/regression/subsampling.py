"""Greedy subsampling of the GPR's support points (§4.2), by incremental elimination.

Start from the rest pose, add a few farthest points (Eq. 7), then repeatedly
the point the current GP predicts worst (Eq. 10) until ``n_points`` are chosen.

The subsampling never refits from scratch. Adding support point ``p`` to a GP
is one step of Gaussian elimination on ``G = K + theta1 I`` over all
candidates: with ``u = G[:, p] - L (L[p] / d)`` the new column of the partial
``L D L^T`` factor and ``d_p = u[p]`` its (signed) pivot, every candidate's
residual updates as ``R -= u (R[p] / d_p)``. The residual at a candidate is
then exactly ``y - K_xS (K_SS + theta1 I)^-1 Y_S``, the error of Eq. 10. Each
addition costs ``O(N (m + D + C))`` for ``N`` candidates, ``m`` points so far,
``D`` inputs and ``C`` outputs; memory is ``8 N n_points`` bytes for the
factor, which is why ``max_candidates`` bounds ``N``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import blas
from tqdm.auto import tqdm

from rigmap.gp.kernels import Kernel

# A pivot this small relative to its kernel diagonal means the candidate is
# numerically a combination of the chosen points; it is skipped.
_PIVOT_TOLERANCE = 1e-12


@dataclass
class Subsample:
    """The chosen support rows (in the order picked) and the worst error at each greedy step."""

    indices: np.ndarray
    max_errors: np.ndarray
    skipped: int


def greedy_subsample(
    X: np.ndarray,
    Y: np.ndarray,
    kernel: Kernel,
    regularization: float,
    n_points: int,
    rest_index: int = 0,
    n_farthest: int = 10,
    progress: bool = False,
) -> Subsample:
    """§4.2 on (normalised) data: rest pose, farthest points (Eq. 7), worst-predicted (Eq. 10).

    See the module docstring for the incremental elimination that makes each
    addition cheap. Candidates whose pivot vanishes (duplicates of chosen
    points, to round-off) are skipped; the result then has fewer points only if
    every remaining candidate is such a duplicate.
    """
    n = len(X)
    target = min(int(n_points), n)
    factor = np.empty((n, target))
    pivots = np.empty(target)
    residual = np.asfortranarray(Y, dtype=np.float64).copy(order="F")  # for in-place BLAS ger
    kernel_column = kernel.columns(X)
    available = np.ones(n, dtype=bool)
    nearest_sq = np.full(n, np.inf)  # squared distance to the closest chosen point
    chosen: list[int] = []
    max_errors: list[float] = []
    skipped = 0
    bar = tqdm(total=target, desc="GPR subsampling", unit="pt", disable=not progress, leave=False)
    while len(chosen) < target and available.any():
        step = len(chosen)
        worst_error = None
        if step == 0:
            index = rest_index
        elif step <= n_farthest:
            index = int(np.argmax(np.where(available, nearest_sq, -1.0)))
        else:
            errors = np.einsum("ij,ij->i", residual, residual)
            errors[~available] = -1.0
            index = int(np.argmax(errors))
            worst_error = float(np.sqrt(errors[index]))
        available[index] = False
        column = kernel_column(index)
        scale = abs(column[index]) + regularization
        column[index] += regularization
        if step:
            column -= factor[:, :step] @ (factor[index, :step] / pivots[:step])
        pivot = column[index]
        if not np.isfinite(pivot) or abs(pivot) <= _PIVOT_TOLERANCE * scale:
            skipped += 1
            continue
        factor[:, step] = column
        pivots[step] = pivot
        # residual -= column ⊗ residual[index] / pivot, in place
        blas.dger(-1.0 / pivot, column, residual[index].copy(), a=residual, overwrite_a=True)
        residual[index] = 0.0
        if step < n_farthest:
            delta = X - X[index]
            np.minimum(nearest_sq, np.einsum("ij,ij->i", delta, delta), out=nearest_sq)
        chosen.append(index)
        if worst_error is not None:
            max_errors.append(worst_error)
        bar.update(1)
    bar.close()
    return Subsample(np.asarray(chosen, dtype=np.int64), np.asarray(max_errors), skipped)
