"""Sparse keys from per-frame values: the fewest keys whose curve stays within a tolerance.

A mapping gives a value on every frame; an animator wants keys to edit. As a bake with
key reduction does in a DCC, keys are placed where the curve needs them: start with the
first and last frame, then repeatedly add, in every segment whose error exceeds the
tolerance, a key at that segment's worst frame, until every frame is within tolerance.
Curves are Béziers (:class:`rigmap.animation.keyframes.FCurve`) whose aligned handles
follow the per-frame curve's own slope at each key (a cubic Hermite with the data's
derivative): far fewer keys than auto-clamped tangents, which flatten at every key that
is a local extreme, and handles an animator edits as usual in Blender or Maya.

:func:`reduce_within_joint_tolerance` states the tolerance where the animator sees it,
in cm on the joints: it tightens the per-control tolerances (in units of each control's
training std) until the rig, evaluated on the reduced curves, stays within it.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from rigmap.animation.keyframes import FCurve, Key
from rigmap.errors import RigmapError

MAX_TIGHTENINGS = 12  # halvings of the control tolerance before giving up (ours)
START_TOLERANCE_STD = 0.05  # first control tolerance, in training stds (ours)


class KeyReductionError(RigmapError, ValueError):
    """Key reduction that cannot reach its tolerance, or bad input; names the control."""


def reduce_curve(values: np.ndarray, tolerance: float, *, control: str | None = None) -> FCurve:
    """The sparse auto-clamped Bézier curve within ``tolerance`` of ``values`` on every frame."""
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 1 or len(values) == 0:
        raise KeyReductionError(f"{control or 'curve'}: expected one value per frame, got "
                                f"shape {values.shape}")  # fmt: skip
    if not np.isfinite(values).all():
        raise KeyReductionError(f"{control or 'curve'}: values are not all finite")
    if not tolerance > 0:
        raise KeyReductionError(f"{control or 'curve'}: tolerance {tolerance} must be > 0")
    frames = np.arange(len(values), dtype=np.float64)
    slopes = np.gradient(values) if len(values) > 1 else np.zeros(1)
    keys = sorted({0, len(values) - 1})
    while True:
        curve = _hermite_curve(values, slopes, keys, control)
        error = np.abs(curve.evaluate(frames) - values)
        added = []
        for first, last in itertools.pairwise(keys):
            inside = error[first + 1 : last]
            if inside.size and inside.max() > tolerance:
                added.append(first + 1 + int(np.argmax(inside)))
        if not added:
            return curve
        keys = sorted(set(keys) | set(added))


def _hermite_curve(values, slopes, keys: list[int], control: str | None) -> FCurve:
    """Keys at ``keys`` with handles a third of the way to each neighbour along the slope."""
    placed = []
    for i, frame in enumerate(keys):
        value, slope = float(values[frame]), float(slopes[frame])
        before = frame - keys[i - 1] if i > 0 else 0
        after = keys[i + 1] - frame if i + 1 < len(keys) else 0
        in_handle = (frame - before / 3, value - slope * before / 3) if before else None
        out_handle = (frame + after / 3, value + slope * after / 3) if after else None
        placed.append(Key(frame, value, "bezier", in_handle, out_handle))
    return FCurve(placed, control=control)


@dataclass(frozen=True)
class ReducedKeys:
    """Keyed curves of the used controls and what the reduction achieved."""

    control_names: tuple[str, ...]
    curves: tuple[FCurve, ...]
    frames: int
    control_tolerance_std: float
    max_joint_error_cm: float

    @property
    def key_count(self) -> int:
        return sum(len(c) for c in self.curves)

    def values(self) -> np.ndarray:
        """``(frames, controls)`` values of the curves on every frame."""
        frames = np.arange(self.frames, dtype=np.float64)
        return np.stack([c.evaluate(frames) for c in self.curves], axis=1)


def reduce_within_joint_tolerance(
    rig, controls: np.ndarray, control_std: np.ndarray, tolerance_cm: float
) -> ReducedKeys:
    """Reduce every used control of ``controls`` (``(F, C)`` full rows) to sparse keys whose
    replay moves no joint more than ``tolerance_cm`` from the per-frame controls' pose."""
    controls = np.asarray(controls, dtype=np.float64)
    used = rig.controls.used_indices
    names = tuple(rig.control_names[i] for i in used)
    if not tolerance_cm > 0:
        raise KeyReductionError(f"joint tolerance {tolerance_cm} cm must be > 0")
    std = np.where(np.asarray(control_std, dtype=np.float64) > 0, control_std, 1.0)
    target = _world(rig, controls)
    tolerance_std = START_TOLERANCE_STD
    for _ in range(MAX_TIGHTENINGS):
        curves = tuple(
            reduce_curve(controls[:, c], tolerance_std * std[k], control=names[k])
            for k, c in enumerate(used)
        )
        replay = controls.copy()
        frames = np.arange(len(controls), dtype=np.float64)
        replay[:, used] = np.stack([curve.evaluate(frames) for curve in curves], axis=1)
        error = float(np.linalg.norm(_world(rig, replay) - target, axis=2).max())
        if error <= tolerance_cm:
            return ReducedKeys(names, curves, len(controls), tolerance_std, error)
        tolerance_std /= 2
    raise KeyReductionError(
        f"key reduction did not reach {tolerance_cm} cm on rig {rig.name!r} after "
        f"{MAX_TIGHTENINGS} tightenings (last {error:.3g} cm at {tolerance_std * 2:.2e} std)"
    )


def _world(rig, controls: np.ndarray) -> np.ndarray:
    pose = rig.pose(controls)
    return np.asarray(pose.positions, dtype=np.float64) + np.asarray(pose.cog)[:, None, :]
