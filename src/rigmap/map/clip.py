"""Map one clip: targets → guess → refinement → editable curves → sparse keys (§6.3, Fig. 8).

:func:`map_clip` takes a clip's targets (world positions of the rig joints a source
drives, from :class:`rigmap.map.JointMap` or given as effectors) and a
:class:`rigmap.map.partial.SubsetMapping` trained on those joints, and returns every
control per frame plus what a user checks: per-frame joint error, foot skate, the
largest frame-to-frame jump, and keys reduced within a tolerance in cm.

What users of retargeting tools ask for, done here: keys on the animator's controls
(used controls only; the rest stay at their defaults), no Euler flips (unwrapped),
feet pinned while planted, IK/FK switches and follow spaces held at their corpus
values (``hold`` globs: a switch flickering between IK and FK is not editable), and
sparse keys. Refinement runs on the world positions of the mapped joints, so it also
corrects where the character stands.
"""

from __future__ import annotations

import fnmatch
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rigmap.errors import RigmapError
from rigmap.map.contact_hold import hold_contacts, reachable_pins
from rigmap.map.contacts import (
    Contacts,
    contact_floors,
    contact_slip,
    detect_contacts,
    foot_skate,
    ground_penetration,
    pin_contacts,
)
from rigmap.map.curves import count_flips, largest_jumps, smooth, unwrap_rotations
from rigmap.map.joint_map import MappedTargets
from rigmap.map.key_reduction import JointLimit, ReducedKeys, reduce_within_joint_tolerance
from rigmap.map.partial import SubsetMapping
from rigmap.map.prior_refinement import DEFAULT_PRIOR_WEIGHT, refine_toward_guess
from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.refine import ComputedJacobian, damped_least_squares
from rigmap.torch_threads import single_threaded


class MapError(RigmapError, ValueError):
    """A clip that cannot be mapped with the given model or settings."""


# The steps :func:`map_clip` reports as each ends (a long clip's progress bar counts them).
MAP_STEPS = ("contacts", "refine", "keys", "score")


def _no_step(name: str) -> None:
    """Report nothing (the default of ``map_clip``'s ``on_step``)."""


@dataclass(frozen=True)
class MapSettings:
    """How a clip is mapped; every default is ours (the paper gives none).

    ``prior_weight`` (cm per training std) pulls refinement toward the guess so poorly
    determined controls do not wander (:mod:`rigmap.map.prior_refinement`); 0 is plain
    Eq. 13, which reaches a few effector targets exactly at the price of that drift.
    ``smoothing_frames`` (Gaussian σ, frames) before key reduction: on the CMU walk at
    120 fps σ = 1 takes the largest control jump from 7.4 to 3.0 training std for 0.02 cm
    more joint error (branch switches of the refinement become short ramps).
    ``foot_weight`` weighs the errors of the ``feet`` joints in that refinement (1: like
    every joint), so planted feet slide less where the rig cannot reach every target.
    Measured on both CMU walks at 120 fps (3 iterations, these defaults against plain
    Eq. 13 without smoothing): largest jump 10.8 -> 3.0 and 3.2 -> 2.6 std, keys at 1 cm
    19.8 -> 12.9 and 15.7 -> 13.3 % of frames × controls, planted-foot skate 0.130 -> 0.105
    and 0.085 -> 0.055 cm/frame (source 0.099 and 0.065), RMS joint error 5.19 -> 5.01 and
    2.99 -> 3.34 cm.
    """

    refine_iterations: int = 3
    damping: float | str = "auto"
    feet: tuple[str, ...] = ()
    pin_feet: bool = True
    smoothing_frames: float = 1.0
    hold: tuple[str, ...] = ("*.ik_fk", "*.follow")
    key_tolerance_cm: float = 0.5
    prior_weight: float = DEFAULT_PRIOR_WEIGHT
    foot_weight: float = 3.0

    def __post_init__(self) -> None:
        if not (isinstance(self.refine_iterations, int) and self.refine_iterations >= 0):
            raise MapError(f"refine_iterations {self.refine_iterations!r} must be an integer >= 0")
        if not self.key_tolerance_cm > 0:
            raise MapError(f"key_tolerance_cm {self.key_tolerance_cm!r} must be > 0")
        if not (np.isfinite(self.foot_weight) and self.foot_weight > 0):
            raise MapError(f"foot_weight {self.foot_weight!r} must be a finite number > 0")
        if not (np.isfinite(self.prior_weight) and self.prior_weight >= 0):
            raise MapError(f"prior_weight {self.prior_weight!r} must be a finite number >= 0")


@dataclass
class MapResult:
    """Everything :func:`map_clip` found for one clip (world cm, rig axes)."""

    rig: str
    source: str
    fps: float
    joint_names: tuple[str, ...]
    controls: np.ndarray  # (F, C) every control, unused ones at their defaults
    targets: np.ndarray  # (F, K, 3) after pinning
    achieved: np.ndarray  # (F, K, 3) the rig's joints at the mapped controls
    keys: ReducedKeys
    contacts: Contacts | None
    skate_source_cm: float
    skate_result_cm: float
    largest_jump_std: float
    seconds: dict[str, float] = field(default_factory=dict)
    penetration_source_cm: float = 0.0  # deepest a contact joint goes below its floor
    penetration_result_cm: float = 0.0
    contact_slip_cm: float = 0.0  # farthest a planted joint is from its pin (output)
    flips: int = 0  # frame-to-frame changes over π of a rotate control (output)

    @property
    def frame_error_cm(self) -> np.ndarray:
        """Per frame, RMS distance over the mapped joints (cm)."""
        return np.sqrt(((self.achieved - self.targets) ** 2).sum(axis=2).mean(axis=1))

    @property
    def n_frames(self) -> int:
        return len(self.controls)


def held_controls(rig, patterns) -> list[int]:
    """Positions among the used controls of those matching ``patterns`` (fnmatch globs)."""
    names = rig.used_controls
    return [k for k, n in enumerate(names) if any(fnmatch.fnmatch(n, p) for p in patterns)]


def map_clip(
    rig,
    targets: MappedTargets,
    mapping: SubsetMapping,
    settings: MapSettings,
    *,
    control_std: np.ndarray,
    hold_values: np.ndarray,
    on_step: Callable[[str], None] = _no_step,
    planted: Contacts | None = None,
) -> MapResult:
    """Map ``targets`` onto ``rig``; ``control_std`` and ``hold_values`` are per used control
    (training-corpus std, and the value a held control keeps, e.g. its corpus median).
    ``on_step`` is called with each of :data:`MAP_STEPS` as it ends (for progress).
    ``planted``: the feet's planted frames when the caller knows them (a path edit holds its
    stance feet on a slope, where the height test of :func:`detect_contacts` finds few);
    None: detected from the targets."""
    joints = mapping.subset.joints
    missing = [j for j in joints if j not in targets.joint_names]
    if missing:
        raise MapError(
            f"{targets.source}: the mapping's joint subset {mapping.subset.name!r} needs joints "
            f"{missing}, which the targets do not have (they drive {list(targets.joint_names)})"
        )
    world = targets.positions[:, [targets.joint_names.index(j) for j in joints]]
    seconds: dict[str, float] = {}
    feet = [f for f in settings.feet if f in joints]  # contact joints the targets drive
    contacts = _contacts(world, feet, joints, targets, planted) if feet else None
    source = world
    if contacts is not None and settings.pin_feet:
        world = reachable_pins(rig, pin_contacts(world, contacts, joints), source, contacts, joints)
    on_step("contacts")
    Y = solve_controls(rig, mapping, world, settings, control_std, hold_values, seconds)
    on_step("refine")
    kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
    Y = smooth(unwrap_rotations(Y, kinds), settings.smoothing_frames)
    limits = []  # with pinning, the planted joints held, then kept near the held pose
    with single_threaded():  # as the refinement: many small rig batches
        if contacts is not None and settings.pin_feet:
            Y = _hold(rig, Y, world, contacts, mapping, settings, control_std, targets.fps, seconds)
            limits = [
                JointLimit(f, contacts.planted[:, k], CONTACT_TOLERANCE_CM)
                for k, f in enumerate(contacts.feet)
            ]
        started = time.perf_counter()
        keys = reduce_within_joint_tolerance(
            rig, rig.expand_used(Y), control_std, settings.key_tolerance_cm, limits=limits
        )
        seconds["keys_s"] = time.perf_counter() - started
    on_step("keys")
    controls = rig.expand_used(keys.values())
    achieved = np.asarray(WorldSubsetRig(rig, joints).evaluate(controls), dtype=np.float64)
    result = MapResult(
        rig.name,
        targets.source,
        targets.fps,
        tuple(joints),
        controls,
        world,
        achieved,
        keys,
        contacts,
        0.0,
        0.0,
        float(largest_jumps(keys.values(), control_std).max()),
        seconds,
        flips=count_flips(keys.values(), kinds),
    )
    if contacts is not None:
        _score_contacts(result, source, settings.pin_feet)
    on_step("score")
    return result


CONTACT_TOLERANCE_CM = 0.05  # key reduction keeps planted joints this close (ours)


def _contacts(world, feet, joints, targets: MappedTargets, planted: Contacts | None) -> Contacts:
    """The given planted frames of the feet the mapping drives, else those detected."""
    if planted is None:
        return detect_contacts(world, feet, joints, targets.fps)
    if planted.planted.shape[0] != len(world) or not set(feet) <= set(planted.feet):
        raise MapError(
            f"{targets.source}: planted frames given for feet {list(planted.feet)} over "
            f"{planted.planted.shape[0]} frames; the targets have {len(world)} frames and "
            f"feet {feet}"
        )
    columns = [planted.feet.index(f) for f in feet]
    return Contacts(tuple(feet), planted.planted[:, columns])


def _hold(rig, Y, pinned, contacts, mapping, settings, control_std, fps, seconds) -> np.ndarray:
    """Planted joints held on their pins by the rig's foot controls (held controls stay)."""
    started = time.perf_counter()
    scale = np.asarray(control_std, dtype=np.float64).copy()
    scale[held_controls(rig, settings.hold)] = 0.0
    held = hold_contacts(
        rig, Y, pinned, contacts, mapping.subset.joints, mapping.subset.origin, scale, fps
    )
    seconds["hold_s"] = time.perf_counter() - started
    seconds["hold_rig_evaluations"] = float(held.rig_evaluations)
    return held.controls


def _score_contacts(result: MapResult, source: np.ndarray, pinned: bool) -> None:
    """Skate, penetration (and with pinning the slip from the pins) of source and result."""
    contacts, joints = result.contacts, result.joint_names
    floors = contact_floors(source, contacts, joints)
    result.skate_source_cm = foot_skate(source, contacts, joints)
    result.skate_result_cm = foot_skate(result.achieved, contacts, joints)
    result.penetration_source_cm = ground_penetration(source, contacts, joints, floors)
    result.penetration_result_cm = ground_penetration(result.achieved, contacts, joints, floors)
    if pinned:
        result.contact_slip_cm = contact_slip(result.achieved, result.targets, contacts, joints)


def solve_controls(rig, mapping, world, settings, control_std, hold_values, seconds) -> np.ndarray:
    """Used controls ``(N, U)`` for world targets ``(N, K, 3)`` of the mapping's joints:
    the mapping's guess with held controls set, then damped least squares on the targets
    (held controls stay), pulled toward the guess by ``settings.prior_weight``
    (:mod:`rigmap.map.prior_refinement`). Adds ``predict_s``, ``refine_s`` (and evaluations)
    to ``seconds``."""
    started = time.perf_counter()
    Y = mapping.predict(world)
    held = held_controls(rig, settings.hold)
    Y[:, held] = np.asarray(hold_values, dtype=np.float64)[held]
    seconds["predict_s"] = time.perf_counter() - started
    if settings.refine_iterations == 0:
        seconds["refine_s"] = 0.0
        return Y
    started = time.perf_counter()
    scale = np.asarray(control_std, dtype=np.float64).copy()
    scale[held] = 0.0  # a control with scale 0 does not move
    if settings.prior_weight > 0:
        result = refine_toward_guess(
            rig,
            mapping.subset.joints,
            Y,
            world,
            prior_weight=settings.prior_weight,
            control_scale=scale,
            damping=settings.damping,
            iterations=settings.refine_iterations,
            joint_weights=[
                settings.foot_weight if j in settings.feet else 1.0 for j in mapping.subset.joints
            ],
        )
    else:  # plain Eq. 13 on the mapped joints
        view = WorldSubsetRig(rig, mapping.subset.joints)
        result = damped_least_squares(
            view,
            Y,
            world,
            ComputedJacobian(view),
            damping=settings.damping,
            max_iterations=settings.refine_iterations,
            control_scale=scale,
            keep_in_range=True,
        )
    seconds["refine_s"] = time.perf_counter() - started
    seconds["refine_rig_evaluations"] = float(result.rig_evaluations)
    return result.Y_used
