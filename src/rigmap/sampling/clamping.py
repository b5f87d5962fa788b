"""Clamping drawn control vectors to the rig's limits, and saying how much was cut.

Gaussian strategies have unbounded tails, so some draws land outside what the
rig accepts; the count tells an engineer whether a sampler's spread is sane
for a rig (many clamped rows = samples piling up on the limits).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from rigmap.sampling.base import SamplerInputError, check_bounds, check_lower_upper


class ClampResult(NamedTuple):
    """Clamped values and the counts of what changed."""

    values: np.ndarray
    n_values: int
    """Single control values moved onto a limit."""
    n_rows: int
    """Control vectors with at least one value moved."""
    per_control: np.ndarray
    """``(C,)`` values moved, per control column."""


def clamp_to_limits(Y, lower, upper, *, copy: bool = True) -> ClampResult:
    """Clamp ``(N, C)`` control vectors into ``[lower, upper]`` per column.

    ``lower``/``upper`` hold one value per column; ``±inf`` means unlimited.
    With ``copy=False`` a float64 ``Y`` is clamped in place (saves one copy of
    a large draw).
    """
    who = "clamp_to_limits"
    array = np.asarray(Y)
    if array.dtype.kind not in "fiu" or array.ndim != 2:
        raise SamplerInputError(
            f"{who}: Y must be a 2-D numeric array (rows, controls), "
            f"got shape {array.shape} dtype {array.dtype}"
        )
    values = np.array(array, dtype=np.float64, copy=copy or array.dtype != np.float64)
    n_columns = values.shape[1]
    lower = check_bounds(lower, n_columns, "lower limits", who)
    upper = check_bounds(upper, n_columns, "upper limits", who)
    check_lower_upper(lower, upper, who)
    if np.isnan(values).any():
        row, column = np.argwhere(np.isnan(values))[0]
        raise SamplerInputError(f"{who}: Y contains NaN (first at row {row}, column {column})")
    outside = (values < lower) | (values > upper)
    per_control = outside.sum(axis=0)
    n_rows = int(outside.any(axis=1).sum())
    del outside
    np.clip(values, lower, upper, out=values)
    return ClampResult(values, int(per_control.sum()), n_rows, per_control)
