"""Standardising inputs and outputs by mean and spread, without blowing up round-off."""

from __future__ import annotations

import numpy as np

# A dimension whose spread is below this fraction of the largest one is centred
# but not scaled: scaling it would blow round-off noise up to unit variance.
_MIN_RELATIVE_STD = 1e-6


def column_scale(values: np.ndarray, shared: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Mean and spread per column (or one spread for all columns when ``shared``)."""
    mean = values.mean(axis=0)
    if shared:
        spread = float(np.sqrt(np.mean((values - mean) ** 2)))
        std = np.full(values.shape[1], spread if spread > 0 else 1.0)
        return mean, std
    std = values.std(axis=0)
    floor = _MIN_RELATIVE_STD * float(std.max(initial=0.0))
    std = np.where((std > floor) & (std > 0), std, 1.0)
    return mean, std
