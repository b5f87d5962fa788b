"""Rigify's human's motion library: the biped's motions, re-keyed onto its controls (§6.1).

Rigify's human (``rigify_human``, evaluated by Blender) is the built-in biped's
kind of character, a little taller, so it gets the biped's motions (:mod:`.biped`,
keyed by its :class:`~.biped.Human` helpers) on a stand-in builder, and
:class:`BipedToRigifyHuman` writes those curves onto Rigify's used controls — what
a TD does to move animation between two rigs (:mod:`.rekey`, shared with the wolf's
library). Train and test clips are the biped's
(the test clips carry the paper's Table 1 names); the seed, and so every take, is
the Rigify human's own.

How the re-keying works (every Rigify channel keyed on the frames its biped
channels are keyed on, with their interpolation):

* rotations go bone for bone. The biped's joint frames are world-aligned at rest
  (rigmap axes: Y up, Z forward, +X the character's left) and turn in Euler XYZ;
  each Rigify bone turns in its own rest frame ``B`` (``REST_FRAMES``, measured on
  the generated rig), so the same turn relative to the parent is ``Bᵀ R B``. The
  arms differ at rest — Rigify's hang in an A-pose, the biped's stretch in a
  T-pose — so an arm bone's turn also carries ``Q``, the smallest rotation from
  Rigify's rest direction of the bone onto the biped's (``Bᵀ Q_parentᵀ R Q B``):
  a biped arm hanging by the side hangs by Rigify's side;
* translations (root, torso, chest, IK feet) turn into the bone's frame, ``Bᵀ t``,
  and scale by ``LENGTH_SCALE`` (Rigify's hip-to-ankle 98.7 cm over the biped's
  86 cm), so a planted foot stays planted as the root travels; an IK hand target
  is placed relative to the shoulder at the arm's own scale (``ARM_SCALE``);
* switches: Rigify's ``IK_FK`` is 0 in IK and 1 in FK, the biped's ``ik_fk`` the
  other way round; the biped's foot roll is Rigify's heel ``rx`` (same sign and
  size, measured); a finger's curl is shared by its master and its two first
  joints (``CURL_SHARES``), its spread turns the master;
* Rigify controls without a biped counterpart (spine FK tweaks, IK stretch, neck
  follow, heel twist and spin, finger length, hip shift, arm and leg twist) get a
  small seeded settle on the clip's first, middle and last keyed frame, like the
  wolf's library (:mod:`.wolf`);
* the biped's eyes, jaw, ball joints, spine middle, arm poles and per-joint finger
  detail are not used controls of Rigify's human: dropped.

Conventions were measured on the generated rig (Rigify's human metarig, Blender
5.0) by reading its bones' rest matrices and moving one control at a time; the
tests check them against the rig. The shares and settle spreads are ours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from rigmap.animation.library import biped as human
from rigmap.animation.library.clip_builder import ClipBuilder
from rigmap.animation.library.rekey import (
    CurveRekeyer,
    SettleChannel,
    Term,
    library_through_stand_in,
    rest_value,
)

#: Rigify cm per biped cm: hip-to-ankle 98.7 / 86 cm
LENGTH_SCALE = 1.15
#: Rigify cm per biped cm along the arm: shoulder-to-wrist 54.2 / 53.1 cm
ARM_SCALE = 1.02
SIDES = {"l": "L", "r": "R"}
MIRROR = np.diag([-1.0, 1.0, 1.0])

#: the left bones' rest frames in rigmap axes (rows: X, Y, Z; columns: the bone's local
#: axes), read from the generated rig; the right side is the mirror ``S B S``
REST_FRAMES_LEFT = {
    "root": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)),
    "neck": ((1.0, 0.0, 0.0), (0.0, 0.9596, -0.2814), (0.0, 0.2814, 0.9596)),
    "head": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "shoulder": ((0.5071, 0.8619, 0.0005), (-0.0001, -0.0006, 1.0), (0.8619, -0.5071, -0.0002)),
    "upper_arm_fk": ((-0.5103, 0.8565, 0.0781), (-0.8330, -0.4697, -0.2923),
                     (-0.2137, -0.2142, 0.9531)),
    "forearm_fk": ((-0.5103, 0.8256, -0.2408), (-0.8330, -0.5441, -0.1002),
                   (-0.2137, 0.1495, 0.9654)),
    "hand_fk": ((-0.5641, 0.7984, -0.2105), (-0.7956, -0.5938, -0.1200),
                (-0.2208, 0.0998, 0.9702)),
    "thigh_fk": ((1.0, 0.0, 0.0), (0.0, -0.9971, -0.0764), (0.0, 0.0764, -0.9971)),
    "shin_fk": ((1.0, 0.0, 0.0), (0.0, -0.9951, 0.0986), (0.0, -0.0986, -0.9951)),
    "foot_fk": ((1.0, 0.0, -0.0012), (-0.0010, -0.5300, -0.8480), (-0.0006, 0.8480, -0.5300)),
}  # fmt: skip
for _bone in ("torso", "hips", "chest", "foot_ik"):  # these lie like the root
    REST_FRAMES_LEFT[_bone] = REST_FRAMES_LEFT["root"]
REST_FRAMES_LEFT["hand_ik"] = REST_FRAMES_LEFT["hand_fk"]
#: Blender rotation modes of the bones that are not Euler XYZ (read from the rig)
ROTATION_MODES = {"shoulder": "YXZ"}
#: the biped's rest direction of each arm bone (left): along +X, its T-pose
BIPED_ARM_DIRECTION = np.array([1.0, 0.0, 0.0])
#: rest positions (cm, world, left side) that place an IK hand relative to the shoulder
BIPED_SHOULDER, BIPED_WRIST = np.array([17.0, 146.0, -1.0]), np.array([70.0, 146.0, -1.0])
RIGIFY_SHOULDER = np.array([19.53, 158.46, -2.67])
RIGIFY_WRIST = np.array([65.94, 130.61, -4.92])
#: biped finger → Rigify finger chain
FINGERS = {"thumb": "thumb", "index": "f_index", "middle": "f_middle", "ring": "f_ring",
           "pinky": "f_pinky"}  # fmt: skip
#: of the biped's curl (its rig's attribute): the master and the first two joints' ``rx``
CURL_SHARES = {"01_master": 0.5, "01": 0.2, "02": 0.2}
SPREAD_SHARE = 0.3  # rad of the master's rz per unit of the biped's spread
KNEE_TWIST_PER_CM = -0.04  # rad of thigh_ik.ry per biped cm of knee pole tx (measured sign)
#: biped controls whose rest value is not 0 (checked against the rig by the tests)
BIPED_DEFAULTS = {"ik_fk": 1.0, "follow": 1.0}
#: Rigify controls whose rest value is not 0 (checked against the rig by the tests)
RIGIFY_DEFAULTS = {"IK_Stretch": 1.0, "neck_follow": 0.5, "sy": 1.0}


def rest_frame(bone: str, side: str | None = None) -> np.ndarray:
    """``B``: the bone's local axes as columns, in rigmap axes (the right side mirrored)."""
    frame = _orthonormal(np.array(REST_FRAMES_LEFT[bone], dtype=np.float64))  # after rounding
    return MIRROR @ frame @ MIRROR if side == "R" else frame


def _orthonormal(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def align(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction ``source`` onto ``target``."""
    a, b = source / np.linalg.norm(source), target / np.linalg.norm(target)
    axis = np.cross(a, b)
    if np.linalg.norm(axis) < 1e-12:
        return np.eye(3)
    angle = math.atan2(np.linalg.norm(axis), float(a @ b))
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


def arm_alignment(bone: str, side: str) -> np.ndarray:
    """``Q`` of an arm bone: Rigify's rest direction (its local Y) onto the biped's."""
    if bone not in ("upper_arm_fk", "forearm_fk", "hand_fk", "hand_ik"):
        return np.eye(3)
    direction = BIPED_ARM_DIRECTION if side == "L" else MIRROR @ BIPED_ARM_DIRECTION
    return align(rest_frame(bone, side)[:, 1], direction)


def euler_matrices(angles: np.ndarray, mode: str = "XYZ") -> np.ndarray:
    """``(N, 3)`` Blender Euler angles (x, y, z) in rotation mode ``mode`` → ``(N, 3, 3)``."""
    order = [("xyz".index(a.lower())) for a in mode]
    return Rotation.from_euler(mode.lower(), np.asarray(angles)[:, order]).as_matrix()


def matrices_to_euler(R: np.ndarray, mode: str = "XYZ") -> np.ndarray:
    """``(N, 3, 3)`` → ``(N, 3)`` Blender Euler angles (x, y, z) in [-π, π], without flips.

    Each rotation has two Euler triples (``(a, b, c)`` and ``(a + π, π − b, c + π)`` in the
    mode's order); row by row the one nearer the previous row's is kept, so keys in between
    interpolate the short way. Angles stay in [-π, π] like the biped's (a turn past π wraps,
    as the biped's own curves do).
    """
    first = Rotation.from_matrix(R).as_euler(mode.lower())
    second = first + np.array([math.pi, 0.0, math.pi])
    second[:, 1] = math.pi - first[:, 1]
    second = (second + math.pi) % (2 * math.pi) - math.pi
    by_order = np.empty_like(first)
    previous = first[0]
    for row in range(len(first)):
        gaps = [float(np.abs(c[row] - previous).sum()) for c in (first, second)]
        by_order[row] = first[row] if gaps[0] <= gaps[1] else second[row]
        previous = by_order[row]
    angles = np.empty_like(by_order)
    for k, axis in enumerate(mode.lower()):
        angles[:, "xyz".index(axis)] = by_order[:, k]
    return angles


# --- the mapping table ------------------------------------------------------------------------
@dataclass(frozen=True)
class BoneTurn:
    """A Rigify bone's Euler rotation from a product of biped joints' rotations.

    ``parent`` names the Rigify bone whose arm alignment ``Q`` the turn is relative to.
    """

    target: str  # Rigify bone
    side: str | None
    sources: tuple[str, ...]  # biped controls with rx/ry/rz channels, multiplied in order
    parent: str | None = None
    axes: str = "xyz"  # the Rigify channels keyed (the root turns about the vertical only)


@dataclass(frozen=True)
class Channel:
    """One Rigify control: its rest value plus weighted biped channels."""

    target: str
    terms: tuple[Term, ...]


def _channel(target: str, *terms: tuple[str, float]) -> Channel:
    return Channel(target, tuple(Term(s, w) for s, w in terms))


def _turns() -> list[BoneTurn]:
    turns = [
        BoneTurn("root", None, ("root",), axes="z"),
        BoneTurn("torso", None, ("cog",)),
        BoneTurn("hips", None, ("hips",)),
        BoneTurn("chest", None, ("chest",)),
        BoneTurn("neck", None, ("neck_1_fk", "neck_2_fk")),
        BoneTurn("head", None, ("head",)),
    ]
    for s, S in SIDES.items():
        turns += [
            BoneTurn("shoulder", S, (f"clavicle_{s}_ctrl",)),
            BoneTurn("upper_arm_fk", S, (f"upper_arm_{s}_fk",)),
            BoneTurn("forearm_fk", S, (f"forearm_{s}_fk",), parent="upper_arm_fk"),
            BoneTurn("hand_fk", S, (f"hand_{s}_fk",), parent="forearm_fk"),
            BoneTurn("hand_ik", S, (f"arm_{s}_ik",)),
            BoneTurn("thigh_fk", S, (f"thigh_{s}_fk",)),
            BoneTurn("shin_fk", S, (f"shin_{s}_fk",)),
            BoneTurn("foot_fk", S, (f"foot_{s}_fk",)),
            BoneTurn("foot_ik", S, (f"leg_{s}_ik",)),
        ]
    return turns


#: Rigify bones whose translations come from the biped's: (bone, side, biped control, axes)
MOVES = (("root", None, "root", "xy"), ("torso", None, "cog", "xyz"),
         ("chest", None, "chest", "xyz"),
         *(("foot_ik", S, f"leg_{s}_ik", "xyz") for s, S in SIDES.items()))  # fmt: skip


def _channels() -> list[Channel]:
    channels = [_channel("torso.head_follow", ("head.follow", -1.0))]
    for s, S in SIDES.items():
        for limb, rigify in (("arm", "upper_arm"), ("leg", "thigh")):
            channels.append(_channel(f"{rigify}_parent.{S}.IK_FK", (f"{limb}_{s}.ik_fk", -1.0)))
        channels += [
            _channel(f"foot_heel_ik.{S}.rx", (f"leg_{s}.roll", 1.0)),
            _channel(f"foot_heel_ik.{S}.rz", (f"leg_{s}.bank", 1.0 if S == "L" else -1.0)),
            _channel(f"thigh_ik.{S}.ry", (f"leg_{s}_pole.tx", KNEE_TWIST_PER_CM)),
        ]
        for finger, chain in FINGERS.items():
            for joint, share in CURL_SHARES.items():
                channels.append(_channel(f"{chain}.{joint}.{S}.rx", (f"{finger}_{s}.curl", share)))
            channels.append(
                _channel(f"{chain}.01_master.{S}.rz", (f"{finger}_{s}.side_curl", SPREAD_SHARE))
            )
    return channels


def _settle_channels() -> list[SettleChannel]:
    channels = [
        SettleChannel("torso.neck_follow", 0.5, 0.3, 0.0, 1.0),
        *(SettleChannel(f"hips.t{axis}", 0.0, 1.0) for axis in "xyz"),
        *(SettleChannel(f"spine_fk{n}.r{axis}", 0.0, 0.04)
          for n in ("", ".001", ".002", ".003") for axis in "xyz"),
    ]  # fmt: skip
    for S in SIDES.values():
        channels += [
            SettleChannel(f"upper_arm_parent.{S}.IK_Stretch", 0.9, 0.1, 0.0, 1.0),
            SettleChannel(f"thigh_parent.{S}.IK_Stretch", 0.9, 0.1, 0.0, 1.0),
            SettleChannel(f"upper_arm_ik.{S}.ry", 0.0, 0.1),
            SettleChannel(f"foot_heel_ik.{S}.ry", 0.0, 0.05),
            *(SettleChannel(f"foot_spin_ik.{S}.r{axis}", 0.0, 0.05) for axis in "xyz"),
            *(SettleChannel(f"{chain}.01_master.{S}.ry", 0.0, 0.05) for chain in FINGERS.values()),
            *(SettleChannel(f"{chain}.01_master.{S}.sy", 1.0, 0.05, 0.8, 1.2)
              for chain in FINGERS.values()),
        ]  # fmt: skip
    return channels


TURNS: tuple[BoneTurn, ...] = tuple(_turns())
CHANNELS: tuple[Channel, ...] = tuple(_channels())
SETTLE_CHANNELS: tuple[SettleChannel, ...] = tuple(_settle_channels())


def _bone_name(bone: str, side: str | None) -> str:
    return bone if side is None else f"{bone}.{side}"


def rigify_controls() -> list[str]:
    """Every Rigify control the library keys (all of them the rig's used controls)."""
    names = [f"{_bone_name(t.target, t.side)}.r{a}" for t in TURNS for a in t.axes]
    names += [f"{_bone_name(bone, side)}.t{a}" for bone, side, _, axes in MOVES for a in axes]
    names += [f"hand_ik.{S}.t{a}" for S in SIDES.values() for a in "xyz"]
    names += [c.target for c in CHANNELS] + [c.target for c in SETTLE_CHANNELS]
    return names


# --- re-keying --------------------------------------------------------------------------------
class BipedToRigifyHuman(CurveRekeyer):
    """Writes a biped motion's nominal curves onto a Rigify human clip builder."""

    source_defaults = BIPED_DEFAULTS

    def key_onto(self, b: ClipBuilder) -> None:
        for turn in TURNS:
            self._turn(b, turn)
        for bone, side, source, axes in MOVES:
            self._move(b, bone, side, source, axes)
        self._hand_targets(b)
        for channel in CHANNELS:
            self._channel(b, channel)
        self._settle(b, SETTLE_CHANNELS)

    # --- channels ---------------------------------------------------------------------------
    def _turn(self, b: ClipBuilder, turn: BoneTurn) -> None:
        sources = [f"{joint}.r{a}" for joint in turn.sources for a in "xyz"]
        frames = self._frames(sources)
        if frames.size == 0:
            return
        R = np.broadcast_to(np.eye(3), (len(frames), 3, 3))
        for joint in turn.sources:
            angles = np.stack([self._value(f"{joint}.r{a}", frames) for a in "xyz"], axis=1)
            R = R @ euler_matrices(angles)
        B = rest_frame(turn.target, turn.side)
        Q = arm_alignment(turn.target, turn.side)
        Q_parent = arm_alignment(turn.parent, turn.side) if turn.parent else np.eye(3)
        local = B.T @ Q_parent.T @ R @ Q @ B
        angles = matrices_to_euler(local, ROTATION_MODES.get(turn.target, "XYZ"))
        bone = _bone_name(turn.target, turn.side)
        for k, axis in enumerate("xyz"):
            if axis in turn.axes:
                self._write(b, f"{bone}.r{axis}", sources, frames, angles[:, k])

    def _move(self, b: ClipBuilder, bone: str, side: str | None, source: str, axes: str) -> None:
        sources = [f"{source}.t{a}" for a in "xyz"]
        frames = self._frames(sources)
        if frames.size == 0:
            return
        world = LENGTH_SCALE * np.stack([self._value(s, frames) for s in sources], axis=1)
        local = world @ rest_frame(bone, side)  # Bᵀ t, row by row
        for k, axis in enumerate("xyz"):
            if axis in axes:
                self._write(b, f"{_bone_name(bone, side)}.t{axis}", sources, frames, local[:, k])

    def _hand_targets(self, b: ClipBuilder) -> None:
        """The biped's IK hands placed relative to Rigify's shoulders."""
        for s, S in SIDES.items():
            sources = [f"arm_{s}_ik.t{a}" for a in "xyz"]
            frames = self._frames(sources)
            if frames.size == 0:
                continue
            mirror = np.eye(3) if S == "L" else MIRROR
            offset = np.stack([self._value(c, frames) for c in sources], axis=1)
            biped = mirror @ BIPED_WRIST + offset - mirror @ BIPED_SHOULDER
            world = mirror @ RIGIFY_SHOULDER + ARM_SCALE * biped - mirror @ RIGIFY_WRIST
            local = world @ rest_frame("hand_ik", S)
            for k, axis in enumerate("xyz"):
                self._write(b, f"hand_ik.{S}.t{axis}", sources, frames, local[:, k])

    def _channel(self, b: ClipBuilder, channel: Channel) -> None:
        sources = [t.source for t in channel.terms]
        frames = self._frames(sources)
        if frames.size == 0:
            return
        values = np.full(len(frames), rest_value(channel.target, RIGIFY_DEFAULTS))
        for term in channel.terms:
            values += term.weight * self._value(term.source, frames)
        self._write(b, channel.target, sources, frames, values)


LIBRARY = library_through_stand_in("rigify_human", human.LIBRARY, BipedToRigifyHuman)
