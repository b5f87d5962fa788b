"""The length-scale line search of §4.1.1: cross-validated error on random half-splits."""

from __future__ import annotations

import numpy as np

from rigmap.gp.kernels import Kernel
from rigmap.gp.solve import solve_regularized
from rigmap.regression.errors import RegressionInputError


def length_scale_cv_errors(
    X: np.ndarray,
    Y: np.ndarray,
    kernel: Kernel,
    regularization: float,
    length_scales: np.ndarray,
    splits: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Mean validation error for each length scale (§4.1.1).

    The same ``splits`` random halves are used for every candidate so the
    comparison is not blurred by which half was drawn. The error is the mean
    squared error over the validation rows and the given output columns.
    """
    n = len(X)
    if n < 4:
        raise RegressionInputError(
            f"length-scale search needs at least 4 samples to split in halves, got {n}"
        )
    statistic = kernel.statistic(X, X)
    halves = [rng.permutation(n) for _ in range(splits)]
    errors = np.empty(len(length_scales))
    for i, length_scale in enumerate(length_scales):
        candidate = kernel.with_length_scale(float(length_scale))
        split_errors = []
        for order in halves:
            train, validate = order[: n - n // 2], order[n - n // 2 :]
            K_train = candidate.from_statistic(statistic[np.ix_(train, train)])
            K_validate = candidate.from_statistic(statistic[np.ix_(validate, train)])
            with np.errstate(all="ignore"):
                W = solve_regularized(K_train, Y[train], regularization).weights
                error = float(np.mean((K_validate @ W - Y[validate]) ** 2))
            split_errors.append(error if np.isfinite(error) else np.inf)
        errors[i] = float(np.mean(split_errors))
    return errors
