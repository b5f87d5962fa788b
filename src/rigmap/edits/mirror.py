"""Left/right mirroring of training data (§7.1: "we always mirror the training data to
automatically double the amount of training data we have").

A mirror reflects the character across its sagittal plane — world ``x → −x`` (the
built-in rigs face +Z with +X their left; the CMU skeletons are built the same way) —
and swaps left and right. On controls and joint rotations that is a permutation (each
channel to its other-side twin, centre channels to themselves) and a sign per channel:
when both sides share the same local axes (the built-in rigs: the builder mirrors
positions, not frames), the reflection of a translation flips its ``x``, and of a
rotation (an axial vector) flips its ``y`` and ``z``. The biped's attributes keep their
sign (its limbs apply the side sign to curl, roll, bank) except the two foot twists about
the vertical axis. :data:`BIPED_FLIPPED` is that table, found from the rig's channel
kinds and checked on rig evaluations in ``tests/test_edits_mirror.py``:
``rig(mirror(y)) = reflect(rig(y))`` for random poses.

A target track (:mod:`rigmap.edits.representation`) mirrors its root differentials too:
``dt`` and the forward step stay, the lateral step and the turn flip, and the start
``(x, z, heading)`` becomes ``(−x, z, −heading)``. Source clips mirror their world joint
positions (reflected, joints swapped), which by the identity above equals evaluating
the mirrored controls, without a second rig evaluation.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from rigmap.edits.representation import TargetError, TargetTrack

# the biped's channel kinds (the text after the last ".") that change sign (see above)
BIPED_FLIPPED = frozenset({"tx", "ry", "rz", "heel_twist", "toe_twist"})
# skeleton mode: exp-map axes ``.y`` / ``.z`` of every joint and of the root's tilt flip
SKELETON_FLIPPED = frozenset({"y", "z"})
ROOT_SIGNS = {"dt": 1.0, "root.step_forward": 1.0, "root.step_lateral": -1.0, "root.turn": -1.0}


def swap_rig_side(name: str) -> str:
    """``upper_arm_l_fk.rx`` ↔ ``upper_arm_r_fk.rx``: the ``_l`` / ``_r`` tokens swapped."""
    return re.sub(r"_([lr])(?=[_.]|$)", lambda m: "_" + ("r" if m.group(1) == "l" else "l"), name)


_BVH_TWINS = {"lhand": "rhand", "rhand": "lhand"}  # CMU names no pattern covers


def swap_bvh_side(name: str) -> str:
    """``LeftKnee`` ↔ ``RightKnee``, ``LHipJoint`` ↔ ``RHipJoint``, ``lhand`` ↔ ``rhand``
    (the CMU names; channels ``<joint>.<axis>`` swap their joint)."""
    joint, dot, rest = name.partition(".")
    if joint in _BVH_TWINS:
        return _BVH_TWINS[joint] + dot + rest
    swapped = re.sub(r"Left|Right", lambda m: "Right" if m.group() == "Left" else "Left", name)
    return re.sub(r"^([LR])(?=[A-Z])", lambda m: "R" if m.group(1) == "L" else "L", swapped)


@dataclass(frozen=True, eq=False)
class ChannelMirror:
    """``mirrored[:, k] = signs[k] * values[:, permutation[k]]`` over ``channels``."""

    channels: tuple[str, ...]
    permutation: np.ndarray
    signs: np.ndarray

    @classmethod
    def by_names(
        cls,
        channels: Sequence[str],
        swap: Callable[[str], str] = swap_rig_side,
        flipped: frozenset[str] = BIPED_FLIPPED,
        fixed: dict[str, float] | None = None,
    ) -> ChannelMirror:
        """Pairs by ``swap``; the sign is −1 for kinds in ``flipped`` (``fixed`` names a
        channel's sign outright: the root differentials)."""
        channels = tuple(channels)
        index = {name: k for k, name in enumerate(channels)}
        permutation, signs = [], []
        for name in channels:
            twin = swap(name)
            if twin not in index:
                raise TargetError(
                    f"mirror: channel {name!r} has no other-side twin {twin!r} among the "
                    f"{len(channels)} channels"
                )
            permutation.append(index[twin])
            if fixed and name in fixed:
                signs.append(fixed[name])
            else:
                signs.append(-1.0 if name.rsplit(".", 1)[-1] in flipped else 1.0)
        return cls(channels, np.array(permutation), np.array(signs))

    def __call__(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=np.float64)
        if values.shape[-1] != len(self.channels):
            raise TargetError(
                f"mirror: values have {values.shape[-1]} columns, the mirror "
                f"{len(self.channels)} channels"
            )
        return values[..., self.permutation] * self.signs


@dataclass(frozen=True, eq=False)
class Mirror:
    """A subject's mirror: its target channels and its joints."""

    channels: ChannelMirror
    joints: np.ndarray  # joint k of the mirror is joint joints[k] reflected

    @classmethod
    def for_rig(cls, track_channels: Sequence[str], joint_names: Sequence[str]) -> Mirror:
        """The built-in biped's mirror (rig mode track channels, rig joint names)."""
        return cls(
            ChannelMirror.by_names(track_channels, swap_rig_side, BIPED_FLIPPED, ROOT_SIGNS),
            joint_permutation(joint_names, swap_rig_side),
        )

    @classmethod
    def for_skeleton(cls, track_channels: Sequence[str], joint_names: Sequence[str]) -> Mirror:
        """A CMU-named BVH skeleton's mirror: exact for a mirror-symmetric skeleton
        (:func:`symmetric_skeleton`); a captured skeleton's own left/right offsets differ
        a little (CMU 131: the hips 1.25 and 1.18 units from the centre), and its
        mirrored clip lands within a few cm of the reflected one."""
        fixed = {**ROOT_SIGNS, "root.height": 1.0}
        return cls(
            ChannelMirror.by_names(track_channels, swap_bvh_side, SKELETON_FLIPPED, fixed),
            joint_permutation(joint_names, swap_bvh_side),
        )

    def track(self, track: TargetTrack) -> TargetTrack:
        if track.channels != self.channels.channels:
            raise TargetError(f"{track.source}: its channels are not the mirror's")
        x, z, heading = track.start
        return replace(
            track,
            values=self.channels(track.values),
            start=(-x, z, -heading),
            source=f"{track.source} (mirrored)",
        )

    def positions(self, positions: np.ndarray) -> np.ndarray:
        """``(F, J, 3)`` world positions reflected across ``x = 0``, joints swapped."""
        return reflect_positions(positions, self.joints)

    def pairs(self, pairs: list) -> list:
        """Example ``(SourceClip, edited track[, frames])`` pairs followed by their mirrors."""
        from rigmap.edits.propagation import SourceClip  # propagation imports this module

        mirrored = [
            (
                SourceClip(self.positions(pair[0].positions), self.track(pair[0].track)),
                self.track(pair[1]),
                *pair[2:],
            )
            for pair in pairs
        ]
        return [*pairs, *mirrored]


def joint_permutation(joint_names: Sequence[str], swap: Callable[[str], str]) -> np.ndarray:
    names = list(joint_names)
    missing = [n for n in names if swap(n) not in names]
    if missing:
        raise TargetError(f"mirror: joints {missing[:4]} have no other-side twin")
    return np.array([names.index(swap(n)) for n in names])


def reflect_positions(positions: np.ndarray, permutation: np.ndarray) -> np.ndarray:
    reflected = np.asarray(positions, dtype=np.float64)[:, permutation].copy()
    reflected[..., 0] *= -1.0
    return reflected


def symmetric_skeleton(skeleton):
    """The skeleton with each offset averaged with its twin's reflection (centre joints
    put on ``x = 0``): the skeleton on which :meth:`Mirror.for_skeleton` is exact."""
    permutation = joint_permutation(skeleton.joint_names, swap_bvh_side)
    reflected = skeleton.offsets[permutation] * np.array([-1.0, 1.0, 1.0])
    return replace(skeleton, offsets=0.5 * (skeleton.offsets + reflected))


def subject_mirror(subject) -> Mirror:
    """The mirror of a :class:`rigmap.edits.subjects.Subject` (rig or skeleton mode)."""
    if subject.mode == "rig":
        return Mirror.for_rig(subject.channels.channels(), subject.joint_names)
    return Mirror.for_skeleton(subject.skeleton.channels(), subject.joint_names)


__all__ = [
    "BIPED_FLIPPED",
    "ChannelMirror",
    "Mirror",
    "reflect_positions",
    "subject_mirror",
    "swap_bvh_side",
    "swap_rig_side",
    "symmetric_skeleton",
]
