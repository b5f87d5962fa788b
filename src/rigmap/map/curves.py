"""Per-frame control curves an animator can edit: no Euler flips, optional smoothing.

A mapping predicts every frame on its own, so a rotation near ±π can jump by 2π between
frames although the pose barely moves; unwrapping removes those jumps (the values stay
equivalent rotations). Smoothing is a Gaussian filter over time (scipy), light by default
in :class:`rigmap.map.clip.MapSettings`: it trades joint accuracy for calmer curves.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from rigmap.errors import RigmapError


class CurveError(RigmapError, ValueError):
    """Curves that cannot be processed; names the control."""


def unwrap_rotations(values: np.ndarray, kinds) -> np.ndarray:
    """``(F, C)`` controls with each ``rotate`` column unwrapped over frames (period 2π)."""
    values = np.asarray(values, dtype=np.float64)
    out = values.copy()
    rotate = np.array([k == "rotate" for k in kinds])
    if values.ndim != 2 or values.shape[1] != len(rotate):
        raise CurveError(f"controls have shape {values.shape}, expected (frames, {len(rotate)})")
    if rotate.any() and len(values) > 1:
        out[:, rotate] = np.unwrap(values[:, rotate], axis=0)
    return out


def smooth(values: np.ndarray, sigma_frames: float) -> np.ndarray:
    """Gaussian smoothing over frames (edges held); ``sigma_frames=0`` returns a copy."""
    values = np.asarray(values, dtype=np.float64)
    if sigma_frames < 0 or not np.isfinite(sigma_frames):
        raise CurveError(f"smoothing sigma {sigma_frames} must be a finite number >= 0 frames")
    if sigma_frames == 0 or len(values) < 2:
        return values.copy()
    return gaussian_filter1d(values, sigma_frames, axis=0, mode="nearest")


def largest_jumps(values: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Per column, the largest frame-to-frame change in units of ``scale`` (e.g. training std)."""
    values = np.asarray(values, dtype=np.float64)
    if len(values) < 2:
        return np.zeros(values.shape[1])
    scale = np.where(np.asarray(scale, dtype=np.float64) > 0, scale, 1.0)
    return np.abs(np.diff(values, axis=0)).max(axis=0) / scale


def count_flips(values: np.ndarray, kinds) -> int:
    """Frame-to-frame changes of more than π on ``rotate`` columns: Euler flips an
    animator would see as a spin (0 on unwrapped curves)."""
    values = np.asarray(values, dtype=np.float64)
    rotate = np.array([k == "rotate" for k in kinds])
    if len(values) < 2 or not rotate.any():
        return 0
    return int((np.abs(np.diff(values[:, rotate], axis=0)) > np.pi).sum())
