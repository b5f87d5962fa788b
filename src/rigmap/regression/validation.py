"""Checks on what a regressor is given: numbers, finite, 2-D, one target row per input row."""

from __future__ import annotations

from typing import Any

import numpy as np

from rigmap.regression.errors import RegressionInputError


def as_float_array(values: Any, where: str) -> np.ndarray:
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as error:
        raise RegressionInputError(f"{where}: expected a numeric array, got {error}") from None
    if array.dtype.kind not in "fiub":
        raise RegressionInputError(f"{where}: expected numbers, got dtype {array.dtype}")
    return array.astype(np.float64, copy=False)


def check_finite(array: np.ndarray, where: str) -> None:
    if not np.isfinite(array).all():
        row, column = np.argwhere(~np.isfinite(array))[0][:2]
        raise RegressionInputError(
            f"{where} contain NaN or infinity (first at row {row}, column {column}); "
            "expected finite numbers"
        )


def check_training_data(X: Any, Y: Any, model: str) -> tuple[np.ndarray, np.ndarray]:
    """Finite 2-D ``X (N, D)`` and ``Y (N, C)`` with the same number of rows."""
    X = as_float_array(X, f"{model}.fit: inputs X")
    Y = as_float_array(Y, f"{model}.fit: targets Y")
    if Y.ndim == 1:
        Y = Y[:, None]
    if X.ndim != 2:
        raise RegressionInputError(f"{model}.fit: expected inputs X of shape (N, D), got {X.shape}")
    if Y.ndim != 2:
        raise RegressionInputError(
            f"{model}.fit: expected targets Y of shape (N, C) or (N,), got {Y.shape}"
        )
    if len(X) != len(Y):
        raise RegressionInputError(
            f"{model}.fit: X has {len(X)} rows but Y has {len(Y)}; expected one target row "
            "per input row"
        )
    if len(X) == 0 or X.shape[1] == 0 or Y.shape[1] == 0:
        raise RegressionInputError(
            f"{model}.fit: expected non-empty data, got X {X.shape} and Y {Y.shape}"
        )
    check_finite(X, f"{model}.fit: inputs X")
    check_finite(Y, f"{model}.fit: targets Y")
    return X, Y
