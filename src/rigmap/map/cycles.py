"""Locomotion lengthened by looping its own cycle, the seam blended (paper §6.3, Fig. 7).

The paper makes long locomotion from a short piece of the animator's data. Here the cycle
is found from the clip's own periodicity: the lag at which the pose seen from the root's
ground point repeats best (:func:`find_cycle`). :func:`loop_cycle` repeats that cycle, each
repeat moved on by the ground distance the root covered in one cycle, and removes the
mismatch at the seam by easing it in over the last frames of each cycle (smoothstep), so
the looped clip has no jump where one cycle meets the next. The clip is taken as straight
locomotion (the cycle's turn, if any, is not repeated). The bounds on the period are ours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.errors import RigmapError

GROUND = [0, 2]  # rig axes: X and Z span the ground, Y is up
MIN_PERIOD_S = 0.4  # ours: the shortest cycle looked for (a fast run's stride)
MAX_PERIOD_S = 2.5  # ours: the longest (a slow walk's stride)


class CycleError(RigmapError, ValueError):
    """A clip too short to hold a cycle, or a loop that cannot be built."""


@dataclass(frozen=True)
class Cycle:
    """Frames ``start`` to ``start + period`` (exclusive) repeat; ``seam_cm`` is the RMS
    joint distance between frame ``start + period`` and frame ``start`` (ground moved)."""

    start: int
    period: int
    seam_cm: float


def local_pose(world: np.ndarray, root: int) -> np.ndarray:
    """``(F, J, 3)`` joints seen from the root's ground point (its X and Z subtracted)."""
    local = np.array(world, dtype=np.float64, copy=True)
    local[:, :, GROUND] -= local[:, root, None][:, :, GROUND]
    return local


def find_cycle(
    world: np.ndarray,
    root: int,
    fps: float,
    *,
    min_period_s: float = MIN_PERIOD_S,
    max_period_s: float = MAX_PERIOD_S,
) -> Cycle:
    """The period (frames) at which the root-relative pose repeats best (the deepest local
    minimum of its mean squared difference over lags, each coordinate's linear drift
    removed), at most half the clip, and the start whose seam is smallest."""
    pose = local_pose(world, root).reshape(len(world), -1)
    frames = len(pose)
    time = np.arange(frames) - (frames - 1) / 2
    local = pose - pose.mean(axis=0)
    if frames > 1:  # a slow drift (a turn, a sinking head) hidden from the comparison
        local -= np.outer(time, time @ local / (time @ time))
    low = max(2, round(min_period_s * fps))
    high = min(frames // 2, round(max_period_s * fps))
    if high < low:
        raise CycleError(
            f"a clip of {frames} frames at {fps:g} fps holds no two cycles of "
            f"{min_period_s:g}-{max_period_s:g} s: give a longer locomotion clip"
        )
    lags = np.arange(1, high + 2)  # one past ``high``: a minimum at ``high`` is seen as one
    scores = np.array([np.mean((local[lag:] - local[:-lag]) ** 2) for lag in lags])
    # a smooth clip differs little from itself a few frames on: the period is the deepest
    # local minimum (the pose returning), never the rise from lag 0
    dips = [k for k in range(1, len(lags) - 1) if scores[k - 1] > scores[k] <= scores[k + 1]]
    dips = [k for k in dips if lags[k] >= low]
    if not dips:
        raise CycleError(
            f"no cycle of {min_period_s:g}-{max_period_s:g} s in a clip of {frames} frames at "
            f"{fps:g} fps: the pose never returns (give straight locomotion of two cycles or more)"
        )
    period = int(lags[min(dips, key=lambda k: scores[k])])
    seams = ((pose[period:] - pose[:-period]) ** 2).reshape(frames - period, -1, 3)
    per_start = np.sqrt(seams.sum(axis=2).mean(axis=1))
    start = int(np.argmin(per_start))
    return Cycle(start, period, float(per_start[start]))


def loop_cycle(
    world: np.ndarray, root: int, cycle: Cycle, frames: int, blend_frames: int
) -> np.ndarray:
    """``frames`` frames of ``cycle`` repeated: each repeat moved on by the root's ground
    travel over a cycle, the seam's mismatch eased in over the cycle's last
    ``blend_frames`` frames so the last frame of a repeat leads into the next's first."""
    world = np.asarray(world, dtype=np.float64)
    a, p = cycle.start, cycle.period
    if a + p >= len(world):
        raise CycleError(f"cycle {a}+{p} frames runs past the clip's {len(world)} frames")
    if not 1 <= blend_frames <= p:
        raise CycleError(f"blend of {blend_frames} frames: expected 1..{p} (the cycle)")
    travel = np.zeros(3)
    travel[GROUND] = world[a + p, root, GROUND] - world[a, root, GROUND]
    residual = world[a + p] - travel - world[a]  # (J, 3): what the seam would jump by
    ramp = np.clip((np.arange(p) - (p - blend_frames)) / blend_frames, 0.0, 1.0)
    ease = ramp * ramp * (3 - 2 * ramp)  # smoothstep: 0 before the blend, 1 at the seam
    smooth = world[a : a + p] - ease[:, None, None] * residual
    index = np.arange(frames)
    repeat = index // p
    return smooth[index % p] + repeat[:, None, None] * travel
