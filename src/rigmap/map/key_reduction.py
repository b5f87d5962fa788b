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
in cm on the joints (tighter on chosen joints and frames: planted feet): after a loose
reduction of each curve, keys are added only at the frames and on the controls that put
a joint over its tolerance, until the rig, evaluated on the reduced curves, stays
within it everywhere (tightening every curve instead keyed 0.33-0.40 of frames ×
controls on the CMU walks, against 0.11-0.13 so).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from rigmap.animation.keyframes import FCurve, Key
from rigmap.errors import RigmapError

# each curve's own tolerance before the joints are checked, training stds (ours): on the
# two CMU walks mapped whole onto the biped (30 fps, 0.5 cm) 0.05 std gave 0.20 keys per
# frame and control, 0.5 std 0.12 and 0.11, 3 std 0.11 and 0.09
START_TOLERANCE_STD = 0.5
KEY_SHARE = 0.25  # keyed at a frame: controls moving a joint by this share of its tolerance (ours)
SENSITIVITY_FRAMES = 8  # frames of the clip probed for the joints' sensitivity (ours)
PROBE_STD = 0.01  # finite-difference step of that probe, in training stds (ours)


class KeyReductionError(RigmapError, ValueError):
    """Key reduction that cannot reach its tolerance, or bad input; names the control."""


def reduce_curve(
    values: np.ndarray, tolerance: float, *, control: str | None = None, keys=()
) -> FCurve:
    """The sparse Bézier curve within ``tolerance`` of ``values`` on every frame, keyed at
    least at ``keys`` (frames that must hold their value exactly, e.g. a contact's)."""
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 1 or len(values) == 0:
        raise KeyReductionError(
            f"{control or 'curve'}: expected one value per frame, got shape {values.shape}"
        )
    if not np.isfinite(values).all():
        raise KeyReductionError(f"{control or 'curve'}: values are not all finite")
    if not tolerance > 0:
        raise KeyReductionError(f"{control or 'curve'}: tolerance {tolerance} must be > 0")
    slopes = data_slopes(values)
    keys = sorted({0, len(values) - 1} | {int(k) for k in keys})
    while True:
        error = np.abs(hermite_values(values, slopes, keys) - values)
        added = []
        for first, last in itertools.pairwise(keys):
            inside = error[first + 1 : last]
            if inside.size and inside.max() > tolerance:
                added.append(first + 1 + int(np.argmax(inside)))
        if not added:
            return _hermite_curve(values, slopes, keys, control)
        keys = sorted(set(keys) | set(added))


def data_slopes(values: np.ndarray) -> np.ndarray:
    """The per-frame curve's own slope (central differences), the keys' handle slopes."""
    return np.gradient(values) if len(values) > 1 else np.zeros(1)


def hermite_values(values: np.ndarray, slopes: np.ndarray, keys) -> np.ndarray:
    """On every frame, the value of :func:`_hermite_curve`'s Bézier (handles a third of the
    way along the slope make it the cubic Hermite of the keys' values and slopes), without
    building the curve: what the reduction evaluates thousands of times."""
    keys = np.asarray(sorted(keys), dtype=np.int64)
    frames = np.arange(len(values))
    if len(keys) == 1:
        return np.full(len(values), float(values[keys[0]]))
    segment = np.clip(np.searchsorted(keys, frames, side="right") - 1, 0, len(keys) - 2)
    a, b = keys[segment], keys[segment + 1]
    width = (b - a).astype(np.float64)
    t = np.clip((frames - a) / width, 0.0, 1.0)
    h00, h10 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t
    h01, h11 = -2 * t**3 + 3 * t**2, t**3 - t**2
    return h00 * values[a] + h10 * width * slopes[a] + h01 * values[b] + h11 * width * slopes[b]


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


@dataclass(frozen=True)
class JointLimit:
    """A tighter tolerance (cm) for one joint on some frames, e.g. a foot while planted."""

    joint: str
    frames: np.ndarray  # (F,) bool
    tolerance_cm: float


def reduce_within_joint_tolerance(
    rig,
    controls: np.ndarray,
    control_std: np.ndarray,
    tolerance_cm: float,
    *,
    limits: tuple[JointLimit, ...] | list[JointLimit] = (),
    start_tolerance_std: float = START_TOLERANCE_STD,
) -> ReducedKeys:
    """Reduce every used control of ``controls`` (``(F, C)`` full rows) to sparse keys whose
    replay moves no joint more than ``tolerance_cm`` (or its ``limits``) from the pose of
    the per-frame controls.

    Each curve is first reduced on its own within ``start_tolerance_std`` training stds;
    then, while a joint is off by more than its tolerance, the worst frame of each run
    of such frames gets keys on the controls that move those joints most there (their
    deviation times the joint's sensitivity to them): keys go where the joints need
    them, not everywhere. A frame keyed on every control replays exactly, so this ends.
    """
    controls = np.asarray(controls, dtype=np.float64)
    used = rig.controls.used_indices
    names = tuple(rig.control_names[i] for i in used)
    if not tolerance_cm > 0:
        raise KeyReductionError(f"joint tolerance {tolerance_cm} cm must be > 0")
    if not start_tolerance_std > 0:
        raise KeyReductionError(f"start tolerance {start_tolerance_std} std must be > 0")
    std = np.where(np.asarray(control_std, dtype=np.float64) > 0, control_std, 1.0)
    std = std[used] if len(std) == len(rig.control_names) != len(used) else std
    limit = _limit_table(rig, len(controls), tolerance_cm, limits)
    values = controls[:, used]
    slopes = np.stack([data_slopes(values[:, k]) for k in range(len(used))], axis=1)
    keys = [
        set(reduce_curve(values[:, k], start_tolerance_std * std[k]).frames.astype(int))
        for k in range(len(used))
    ]
    replay = np.stack(
        [hermite_values(values[:, k], slopes[:, k], keys[k]) for k in range(len(used))], axis=1
    )
    target = _world(rig, controls)
    sensitivity = _sensitivity(rig, controls, std)
    rows = controls.copy()
    rows[:, used] = replay
    error = np.linalg.norm(_world(rig, rows) - target, axis=2)
    while True:
        over = error > limit
        if not over.any():
            curves = tuple(
                _hermite_curve(values[:, k], slopes[:, k], sorted(keys[k]), names[k])
                for k in range(len(used))
            )
            return ReducedKeys(
                names, curves, len(controls), start_tolerance_std, float(error.max())
            )
        changed = set()
        for f in _worst_frames(error / limit, over):
            deviation = np.abs(replay[f] - values[f]) / std
            changed |= _keys_for_frame(f, deviation, sensitivity, error[f], limit[f], keys)
        if not changed:
            raise KeyReductionError(
                f"key reduction on rig {rig.name!r}: a joint is off by "
                f"{error.max():.3g} cm on a frame keyed on every control"
            )
        dirty = np.zeros(len(controls), dtype=bool)  # frames whose replay changed
        for k in changed:
            new = hermite_values(values[:, k], slopes[:, k], keys[k])
            dirty |= new != replay[:, k]
            replay[:, k] = new
        rows[:, used] = replay
        error[dirty] = np.linalg.norm(_world(rig, rows[dirty]) - target[dirty], axis=2)


def _limit_table(rig, n_frames: int, tolerance_cm: float, limits) -> np.ndarray:
    """``(F, J)`` tolerance of every joint on every frame (cm)."""
    table = np.full((n_frames, len(rig.joint_names)), float(tolerance_cm))
    for item in limits:
        if item.joint not in rig.joint_names:
            raise KeyReductionError(
                f"joint limit on {item.joint!r}: rig {rig.name!r} has no such joint"
            )
        mask = np.asarray(item.frames, dtype=bool)
        if mask.shape != (n_frames,) or not item.tolerance_cm > 0:
            raise KeyReductionError(
                f"joint limit on {item.joint!r}: expected {n_frames} frame "
                "flags and a tolerance > 0 cm"
            )
        j = rig.joint_names.index(item.joint)
        table[mask, j] = np.minimum(table[mask, j], item.tolerance_cm)
    return table


def _worst_frames(ratio: np.ndarray, over: np.ndarray) -> list[int]:
    """The frame of largest error / tolerance in each run of frames with a joint over."""
    bad = over.any(axis=1)
    worst = ratio.max(axis=1)
    marks = np.concatenate([[False], bad, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(marks))
    return [a + int(np.argmax(worst[a:b])) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _keys_for_frame(f, deviation, sensitivity, error, limit, keys) -> set[int]:
    """Key frame ``f`` on the controls that move its joints over tolerance the most:
    those whose estimated share (sensitivity × deviation) is at least
    :data:`KEY_SHARE` of a joint's tolerance, else the largest share; returns them."""
    joints = np.flatnonzero(error > limit)
    share = sensitivity[joints] * deviation[None, :] / limit[joints, None]  # (j, U)
    score = share.max(axis=0)
    score[[k for k in range(len(keys)) if f in keys[k]]] = -1.0
    chosen = set(np.flatnonzero(score >= KEY_SHARE).tolist())
    if not chosen and score.max() > 0:
        chosen = {int(np.argmax(score))}
    if not chosen:  # every share estimated 0: key whatever still deviates
        chosen = {int(k) for k in np.flatnonzero(deviation > 0) if f not in keys[k]}
    for k in chosen:
        keys[k].add(int(f))
    return chosen


def _sensitivity(rig, controls: np.ndarray, std: np.ndarray) -> np.ndarray:
    """``(J, U)`` how far each joint moves per training std of each used control (cm), the
    most over a few frames of the clip (forward differences of :data:`PROBE_STD`)."""
    used = rig.controls.used_indices
    picks = np.unique(np.linspace(0, len(controls) - 1, min(SENSITIVITY_FRAMES, len(controls))))
    base = controls[picks.astype(int)]
    probes = np.repeat(base[None], len(used), axis=0)  # (U, S, C)
    for k, c in enumerate(used):
        probes[k, :, c] += PROBE_STD * std[k]
    moved = _world(rig, probes.reshape(-1, controls.shape[1])).reshape(
        len(used), len(base), len(rig.joint_names), 3
    )
    shift = np.linalg.norm(moved - _world(rig, base)[None], axis=3) / PROBE_STD  # (U, S, J)
    return shift.max(axis=1).T


def _world(rig, controls: np.ndarray) -> np.ndarray:
    pose = rig.pose(controls)
    return np.asarray(pose.positions, dtype=np.float64) + np.asarray(pose.cog)[:, None, :]
