"""Foot contacts: when a foot is planted, how much it slides, and pinning it in place.

Sliding feet are the first thing an animator sees in retargeted mocap. A foot joint is
*planted* on frames where it is near its own floor height and moving slowly; the
thresholds are ours (the paper gives none): within 4 cm of the clip's 5th-percentile
height of that joint and below 25 cm/s horizontally, with gaps shorter than 0.05 s
closed and plants shorter than 0.1 s dropped (mocap jitter would split one step).
Foot skate is the mean horizontal distance a planted foot moves per frame. Pinning
replaces a planted foot's horizontal position by its mean over each planted interval,
before the targets are mapped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.errors import RigmapError

HEIGHT_TOLERANCE_CM = 4.0
SPEED_TOLERANCE_CM_S = 25.0
MIN_GAP_S = 0.05
MIN_PLANT_S = 0.1
FLOOR_PERCENTILE = 5.0
UP = 1  # rig axes: Y up; X and Z span the ground


class ContactError(RigmapError, ValueError):
    """Contact detection given unusable input."""


@dataclass(frozen=True)
class Contacts:
    """``planted[f, k]``: foot ``feet[k]`` is planted at frame ``f``."""

    feet: tuple[str, ...]
    planted: np.ndarray

    def intervals(self, k: int) -> list[tuple[int, int]]:
        """The planted runs of foot ``k`` as ``(first, last)`` frames, inclusive."""
        return _runs(self.planted[:, k], True)


def detect_contacts(
    positions: np.ndarray,
    feet: list[str] | tuple[str, ...],
    joint_names: list[str] | tuple[str, ...],
    fps: float,
    *,
    height_tolerance_cm: float = HEIGHT_TOLERANCE_CM,
    speed_tolerance_cm_s: float = SPEED_TOLERANCE_CM_S,
) -> Contacts:
    """Planted frames of each foot joint from world positions ``(F, J, 3)`` in cm."""
    positions = np.asarray(positions, dtype=np.float64)
    missing = [f for f in feet if f not in joint_names]
    if missing:
        raise ContactError(f"foot joints {missing} are not among the joints {list(joint_names)}")
    if positions.ndim != 3 or positions.shape[1] != len(joint_names) or len(positions) == 0:
        raise ContactError(
            f"positions have shape {positions.shape}, expected (F>0, {len(joint_names)}, 3)"
        )
    columns = [list(joint_names).index(f) for f in feet]
    foot = positions[:, columns]
    height = foot[:, :, UP]
    floor = np.percentile(height, FLOOR_PERCENTILE, axis=0)
    speed = np.zeros(height.shape)
    if len(foot) > 1:
        step = np.linalg.norm(np.diff(foot[:, :, [0, 2]], axis=0), axis=2) * fps
        speed[1:] = step
        speed[0] = step[0]
    planted = (height <= floor + height_tolerance_cm) & (speed <= speed_tolerance_cm_s)
    for k in range(planted.shape[1]):
        planted[:, k] = _debounce(planted[:, k], round(MIN_GAP_S * fps), round(MIN_PLANT_S * fps))
    return Contacts(tuple(feet), planted)


def _runs(flags: np.ndarray, value: bool) -> list[tuple[int, int]]:
    """``(first, last)`` of each run of ``value`` in ``flags``, inclusive."""
    marks = np.concatenate([[False], flags == value, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(marks))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _debounce(flags: np.ndarray, min_gap: int, min_plant: int) -> np.ndarray:
    """Close interior gaps shorter than ``min_gap`` frames, then drop shorter plants."""
    flags = flags.copy()
    for first, last in _runs(flags, False):
        if 0 < first and last < len(flags) - 1 and last - first + 1 < min_gap:
            flags[first : last + 1] = True
    for first, last in _runs(flags, True):
        if last - first + 1 < min_plant:
            flags[first : last + 1] = False
    return flags


def foot_skate(positions: np.ndarray, contacts: Contacts, joint_names) -> float:
    """Mean horizontal slide of planted feet, cm per frame (frames planted at f-1 and f)."""
    positions = np.asarray(positions, dtype=np.float64)
    columns = [list(joint_names).index(f) for f in contacts.feet]
    foot = positions[:, columns][:, :, [0, 2]]
    if len(foot) < 2:
        return 0.0
    both = contacts.planted[1:] & contacts.planted[:-1]
    if not both.any():
        return 0.0
    slide = np.linalg.norm(np.diff(foot, axis=0), axis=2)
    return float(slide[both].mean())


def pin_contacts(positions: np.ndarray, contacts: Contacts, joint_names) -> np.ndarray:
    """A copy with each planted interval's foot held at its mean horizontal position."""
    pinned = np.array(positions, dtype=np.float64, copy=True)
    for k, name in enumerate(contacts.feet):
        j = list(joint_names).index(name)
        for first, last in contacts.intervals(k):
            pinned[first : last + 1, j, 0] = pinned[first : last + 1, j, 0].mean()
            pinned[first : last + 1, j, 2] = pinned[first : last + 1, j, 2].mean()
    return pinned


def contact_floors(positions: np.ndarray, contacts: Contacts, joint_names) -> np.ndarray:
    """Per contact joint, its median height on its planted frames (cm): the height it
    stands at on the floor (its clip's 5th-percentile height if it is never planted)."""
    positions = np.asarray(positions, dtype=np.float64)
    height = positions[:, [list(joint_names).index(f) for f in contacts.feet], UP]
    floors = np.percentile(height, FLOOR_PERCENTILE, axis=0)
    for k in range(len(contacts.feet)):
        if contacts.planted[:, k].any():
            floors[k] = np.median(height[contacts.planted[:, k], k])
    return floors


def ground_penetration(positions: np.ndarray, contacts: Contacts, joint_names, floors) -> float:
    """The deepest any contact joint goes below its floor height (``floors``, cm) on any
    frame, in cm; 0 when none does. Ours: the source's own is the bar to meet."""
    positions = np.asarray(positions, dtype=np.float64)
    height = positions[:, [list(joint_names).index(f) for f in contacts.feet], UP]
    return float(np.maximum(np.asarray(floors)[None] - height, 0.0).max(initial=0.0))


def contact_slip(positions: np.ndarray, pinned: np.ndarray, contacts: Contacts, joint_names):
    """The largest horizontal distance (cm) of a planted joint from its pin in ``pinned``."""
    columns = [list(joint_names).index(f) for f in contacts.feet]
    gap = (
        np.asarray(positions)[:, columns][:, :, [0, 2]]
        - np.asarray(pinned)[:, columns][:, :, [0, 2]]
    )
    distance = np.linalg.norm(gap, axis=2)
    return float(distance[contacts.planted].max(initial=0.0))
