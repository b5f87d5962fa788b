"""Smooth scalar fields for sculpting shapes and painting weights procedurally.

Region masks and falloffs as plain numpy functions of positions, so a
character script can say "the lower lip, fading out over 1 cm" in one line.
"""

from __future__ import annotations

import numpy as np


def smoothstep(edge0: float, edge1: float, x) -> np.ndarray:
    """0 below ``edge0``, 1 above ``edge1``, C1-smooth in between (reversed if edge0 > edge1)."""
    t = np.clip((np.asarray(x, dtype=np.float64) - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def gaussian_bump(points: np.ndarray, center, radii) -> np.ndarray:
    """``exp(-|(p - c) / r|^2 / 2)`` with per-axis radii (cm); ``None`` radius ignores that axis."""
    points = np.asarray(points, dtype=np.float64)
    total = np.zeros(len(points))
    for axis, (c, r) in enumerate(zip(center, radii, strict=True)):
        if r is None:
            continue
        total += ((points[:, axis] - c) / r) ** 2
    return np.exp(-0.5 * total)


def ramps_to_weights(ramps: list[np.ndarray]) -> np.ndarray:
    """Chain weights from nested ramps ``a_1 >= a_2 >= ...`` in [0, 1]: ``(V, len+1)``.

    Bone 0 gets ``1 - a_1``, bone k gets ``a_k - a_{k+1}``, the last ``a_n``:
    a partition of unity that hands a vertex along a chain smoothly.
    """
    stacked = [np.ones_like(ramps[0]), *ramps, np.zeros_like(ramps[0])]
    weights = np.stack([stacked[k] - stacked[k + 1] for k in range(len(stacked) - 1)], axis=1)
    if np.any(weights < -1e-12):
        raise ValueError("chain ramps must be nested (each at most the previous one)")
    return np.clip(weights, 0.0, None)
