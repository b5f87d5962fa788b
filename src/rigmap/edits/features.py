"""Source features of §4.5: what the two GP predictors see of the source clip.

Kinematic features ``x(k)``: the skeleton's joint positions now, 0.125 s ago and 0.125 s
ahead (frames clamped at the clip's ends), all moved so the *current* skeleton's root is
at the origin facing forward — the heading (turn about +Y, from the ``left`` → ``right``
joint axis) removed. The paper's literal "zero global orientation" (the root's whole
rotation removed) is the option ``frame="root_rotation"`` when root rotations are given.

Acceleration features ``x(a)``: the second finite difference of the joint positions
relative to the root (per second², so clips of other frame rates compare), smoothed
over a 0.125 s window (a box filter: the paper does not name the window).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

from rigmap.errors import RigmapError
from rigmap.regression.placement import turn_matrix

WINDOW_S = 0.125  # §4.5


class FeatureError(RigmapError, ValueError):
    """A clip from which features cannot be computed; names the joint or frame."""


def heading_from_axis(positions: np.ndarray, left: int, right: int) -> np.ndarray:
    """Per frame, the turn about +Y taking +Z to the body's forward (``lateral × up``)."""
    lateral = positions[:, left] - positions[:, right]
    forward_x, forward_z = -lateral[:, 2], lateral[:, 0]
    if np.any(np.hypot(forward_x, forward_z) < 1e-9):
        raise FeatureError("left and right joints are vertically aligned on some frame: no heading")
    return np.arctan2(forward_x, forward_z)


def window_frames(fps: float) -> int:
    """0.125 s in whole frames (at least one)."""
    return max(1, round(WINDOW_S * fps))


def kinematic_features(
    positions: np.ndarray,
    fps: float,
    *,
    root: int,
    left: int,
    right: int,
    frame: str = "heading",
    root_rotations: np.ndarray | None = None,
) -> np.ndarray:
    """``(F, 9J)``: the skeleton at t − w, t, t + w in the frame of the skeleton at t."""
    positions = _checked(positions)
    n = len(positions)
    w = window_frames(fps)
    rotation = _frame_rotations(positions, left, right, frame, root_rotations)
    origin = positions[:, root]
    blocks = []
    for shift in (-w, 0, w):
        other = positions[np.clip(np.arange(n) + shift, 0, n - 1)]
        local = np.einsum("nba,njb->nja", rotation, other - origin[:, None, :])  # Rᵀ (p − o)
        blocks.append(local.reshape(n, -1))
    return np.concatenate(blocks, axis=1)


def acceleration_features(positions: np.ndarray, fps: float, *, root: int) -> np.ndarray:
    """``(F, 3J)``: smoothed second differences of root-relative joint positions (per s²)."""
    positions = _checked(positions)
    relative = positions - positions[:, root : root + 1]
    padded = np.concatenate([relative[:1], relative, relative[-1:]])
    acceleration = (padded[:-2] - 2.0 * padded[1:-1] + padded[2:]) * fps**2
    smoothed = uniform_filter1d(acceleration, size=window_frames(fps), axis=0, mode="nearest")
    return smoothed.reshape(len(positions), -1)


def _frame_rotations(positions, left, right, frame, root_rotations) -> np.ndarray:
    if frame == "heading":
        return turn_matrix(heading_from_axis(positions, left, right))
    if frame == "root_rotation":
        if root_rotations is None:
            raise FeatureError("frame 'root_rotation' needs the root's rotations (F, 3, 3)")
        rotations = np.asarray(root_rotations, dtype=np.float64)
        if rotations.shape != (len(positions), 3, 3):
            raise FeatureError(
                f"root rotations have shape {rotations.shape}, expected ({len(positions)}, 3, 3)"
            )
        return rotations
    raise FeatureError(f"frame {frame!r} must be 'heading' or 'root_rotation'")


def _checked(positions) -> np.ndarray:
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 3 or positions.shape[2] != 3 or len(positions) < 3:
        raise FeatureError(f"joint positions must be (F >= 3, J, 3), got {positions.shape}")
    if not np.isfinite(positions).all():
        f, j = np.argwhere(~np.isfinite(positions).all(axis=2))[0]
        raise FeatureError(f"joint {j} is not finite at frame {f}")
    return positions
