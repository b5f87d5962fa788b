"""The characters edits are learned on: a built-in rig (rig mode) or a BVH skeleton.

A :class:`Subject` turns its clips into :class:`~rigmap.edits.propagation.SourceClip`
objects (world joint positions for the features, a target track for the GPs) and turns
any track back into joint positions in cm, for the joint errors:

- :func:`rig_subject` — a built-in rig's motion library (:mod:`rigmap.animation.library`),
  played on its used controls; positions from ``rig.pose`` (COG-relative + the COG).
- :func:`skeleton_subject` — BVH clips (the CMU walks of ``../shared/mocap/``); their
  length unit becomes cm by the ratio of the biped's leg (hip → ankle, cm) to the
  skeleton's (ours: the CMU conversion has no stated unit).

Joint errors compare positions relative to the root (COG or root joint), world-oriented;
where the root goes is reported apart, as root drift.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from rigmap.animation import read_bvh
from rigmap.animation.library import build_clip, motion_library
from rigmap.edits.pairs import read_clip
from rigmap.edits.propagation import FeatureJoints, SourceClip
from rigmap.edits.representation import TargetError, TargetTrack
from rigmap.edits.rig_mode import RigChannels, full_controls, rig_controls, rig_targets
from rigmap.edits.skeleton_mode import Skeleton, skeleton_positions, skeleton_targets
from rigmap.edits.transitions import TRANSITION_MOTIONS

# joints of the biped the features leave out: fingers, eyes and jaw (the body's motion is
# what the edits depend on; ours)
_DETAIL: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class Subject:
    """A character: its mode, feature joints, cm per length unit, and ``positions(track)``
    (``(F, J, 3)`` world joint positions in cm)."""

    name: str
    mode: str
    joints: FeatureJoints
    cm_per_unit: float
    positions: Callable[[TargetTrack], np.ndarray]
    channels: RigChannels | None = None  # rig mode
    skeleton: Skeleton | None = None  # skeleton mode
    joint_names: tuple[str, ...] = ()  # the names of positions(track)'s joints

    def relative_cm(self, track: TargetTrack) -> np.ndarray:
        """Joint positions relative to the root, world-oriented, cm."""
        p = self.positions(track)
        return p - p[:, self.joints.root : self.joints.root + 1]

    def source(self, track: TargetTrack) -> SourceClip:
        return SourceClip(self.positions(track) / self.cm_per_unit, track)


def rig_subject(
    rig,
    root_channels=("root.tx", "root.tz", "root.ry"),
    heading_joints=("pelvis", "thigh_l", "thigh_r"),
    root_signs=(1.0, 1.0, 1.0),
) -> Subject:
    """Rig mode on a built-in rig (see the module docstring); ``root_signs``: the root
    channels' signs to rigmap's axes (:class:`~rigmap.edits.rig_mode.RigChannels`)."""
    channels = RigChannels(
        tuple(rig.used_controls), tuple(root_channels), tuple(float(s) for s in root_signs)
    )
    used = rig.controls.used_indices
    defaults = rig.controls.defaults

    def positions(track: TargetTrack) -> np.ndarray:
        # one thread: the rig's many small tensor ops lose more to thread hand-offs than they
        # gain (measured: 87 frames of the biped 0.40 s on two threads, 0.06 s on one)
        with threadpool_limits(limits=1):
            pose = rig.pose(full_controls(rig_controls(track, channels), used, defaults))
        return np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]

    names = list(rig.joint_names)
    joints = _feature_joints(
        names, [n for n in names if not any(d in n for d in _DETAIL)], heading_joints
    )
    return Subject(
        rig.name, "rig", joints, 1.0, positions, channels=channels, joint_names=tuple(names)
    )


def rig_clip(rig, channels: RigChannels, clip_name: str, seed: int) -> TargetTrack:
    """One clip of the rig's motion library (seeded variation) as a target track; or one of
    the edit study's transition motions (:mod:`rigmap.edits.transitions`)."""
    motion = TRANSITION_MOTIONS.get(rig.name, {}).get(clip_name)
    if motion is None:
        _, motion = motion_library(rig.name).find(clip_name)
    clip = build_clip(rig.name, motion, seed=seed)
    controls = clip.evaluate(rig.control_names, rig.controls.defaults)
    return rig_targets(
        controls[:, rig.controls.used_indices],
        channels,
        clip.fps,
        source=f"{clip_name} (seed {seed})",
    )


def skeleton_subject(
    reference_bvh: str | Path,
    cm_per_unit: float,
    name: str,
    heading_joints=("Hips", "LeftHip", "RightHip"),
) -> Subject:
    """Skeleton mode on a BVH skeleton; every later clip must have the same skeleton."""
    skeleton = Skeleton.of(read_bvh(reference_bvh))
    names = list(skeleton.joint_names)
    moving = [n for j, n in enumerate(names) if j == 0 or np.linalg.norm(skeleton.offsets[j]) > 0]
    joints = _feature_joints(names, moving, heading_joints)

    def positions(track: TargetTrack) -> np.ndarray:
        return skeleton_positions(track, skeleton) * cm_per_unit

    return Subject(
        name,
        "skeleton",
        joints,
        cm_per_unit,
        positions,
        skeleton=skeleton,
        joint_names=tuple(names),
    )


PLAYS = ("forward", "reversed", "double_speed")


def skeleton_clip(subject: Subject, path: str | Path, play: str = "forward") -> TargetTrack:
    """A BVH clip as a target track (:func:`read_skeleton_clip` without its notes)."""
    return read_skeleton_clip(subject, path, play).track


@dataclass(frozen=True, eq=False)
class SkeletonClip:
    """A BVH clip of a skeleton-mode subject: its target track, the file frame that is the
    track's frame 0 (1 when an added T-pose was cut), and what was done to the file."""

    track: TargetTrack
    start: int
    notes: tuple[str, ...]


def read_skeleton_clip(subject: Subject, path: str | Path, play: str = "forward") -> SkeletonClip:
    """A BVH clip checked against the subject's skeleton (the same joints and hierarchy;
    another performer's bone lengths are replaced by the subject's: the clip's rotations
    and root path played on the subject's skeleton). An added T-pose at frame 0 is cut and
    capture glitches are repaired from their neighbours (:func:`rigmap.edits.pairs.read_clip`),
    each said in the notes. ``play`` ``"reversed"`` (walking backwards: the poses of the
    clip, its motion turned round) or ``"double_speed"`` (every other frame) makes motion
    unlike the clip for Fig 4's out-of-distribution test where no other clip of the
    skeleton exists (ours)."""
    if play not in PLAYS:
        raise TargetError(f"{path}: play {play!r} must be one of {PLAYS}")
    clip = read_clip(path)
    motion = clip.motion
    subject.skeleton.check_same(Skeleton.of(motion), str(path))
    if play != "forward":
        values = motion.values[::-1] if play == "reversed" else motion.values[::2]
        motion = replace(motion, values=values.copy(), source=f"{motion.source} ({play})")
    return SkeletonClip(skeleton_targets(motion), clip.start, clip.notes)


#: the BVH joints whose offsets make the left leg (the 131 conversion's names; the edits
#: of conf/edit/ name that conversion's joints too)
BVH_LEG = ("LeftKnee", "LeftAnkle")


def leg_length_cm_per_unit(
    rig,
    bvh_path: str | Path,
    rig_leg=("thigh_l", "shin_l", "foot_l"),
    bvh_leg=BVH_LEG,
) -> float:
    """cm per BVH unit: the rig's rest hip → knee → ankle length over the skeleton's."""
    rest = np.asarray(rig.evaluate(rig.default_controls(1)))[0]
    names = list(rig.joint_names)
    rig_length = sum(
        np.linalg.norm(rest[names.index(a)] - rest[names.index(b)])
        for a, b in itertools.pairwise(rig_leg)
    )
    motion = read_bvh(bvh_path)
    bvh_length = sum(np.linalg.norm(motion.offsets[motion.joint_index(j)]) for j in bvh_leg)
    return float(rig_length / bvh_length)


def _feature_joints(names: list[str], chosen: Sequence[str], heading_joints) -> FeatureJoints:
    missing = [n for n in heading_joints if n not in names]
    if missing:
        raise TargetError(f"heading joints {missing} are not among the joints {names[:8]}…")
    root, left, right = (names.index(n) for n in heading_joints)
    return FeatureJoints(tuple(names.index(n) for n in chosen), root, left, right)
