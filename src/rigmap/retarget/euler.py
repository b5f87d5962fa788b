"""Rotation matrices back to Euler angles, for all six rotation orders.

The inverse of :func:`rigmap.rigs.engine.transforms.euler_matrix`: order
``"xyz"`` means rotate about x first, then y, then z, so ``R = Rz @ Ry @ Rx``.
A script that orients a control in world space must write its channels as
Euler angles in that control's own rotation order.
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.engine.transforms import ROTATION_ORDERS

# cyclic orders (xyz, yzx, zxy) and their mirrors (xzy, yxz, zyx) differ in sign
_EVEN_ORDERS = ("xyz", "yzx", "zxy")
# below this cos of the middle angle the first and last axes line up (gimbal lock)
_GIMBAL_COS = 1e-9


def matrix_to_euler(R, order: str = "xyz") -> np.ndarray:
    """``(..., 3, 3)`` rotations -> ``(..., 3)`` angles (x, y, z; radians) in ``order``.

    The middle angle is kept in [-π/2, π/2]; in gimbal lock (middle angle ±π/2)
    the last angle is set to 0 and the first carries the whole rotation.
    """
    if order not in ROTATION_ORDERS:
        raise ValueError(f"rotation order must be one of {ROTATION_ORDERS}, got {order!r}")
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"matrix_to_euler: expected (..., 3, 3) matrices, got {R.shape}")
    i, j, k = ("xyz".index(axis) for axis in order)  # applied first, second, last
    sign = 1.0 if order in _EVEN_ORDERS else -1.0
    # R = R_k(c) R_j(b) R_i(a): row k gives a and b, column i gives b and c
    cos_b = np.hypot(R[..., k, j], R[..., k, k])
    b = np.arctan2(-sign * R[..., k, i], cos_b)
    a = np.arctan2(sign * R[..., k, j], R[..., k, k])
    c = np.arctan2(sign * R[..., j, i], R[..., i, i])
    locked = cos_b < _GIMBAL_COS
    if np.any(locked):
        # only a ± c is defined: put it all in a (row j of R_j is untouched by R_j)
        a = np.where(locked, np.arctan2(-sign * R[..., j, k], R[..., j, j]), a)
        c = np.where(locked, 0.0, c)
    angles = np.empty(R.shape[:-1], dtype=np.float64)
    angles[..., i], angles[..., j], angles[..., k] = a, b, c
    return angles


def euler_to_matrix(angles, order: str = "xyz") -> np.ndarray:
    """``(..., 3)`` angles -> ``(..., 3, 3)``, by the rig engine's own definition."""
    import torch

    from rigmap.rigs.engine.transforms import euler_matrix

    angles = np.asarray(angles, dtype=np.float64)
    flat = torch.from_numpy(np.ascontiguousarray(angles.reshape(-1, 3)))
    return euler_matrix(flat, order).numpy().reshape(*angles.shape[:-1], 3, 3)
