"""The wolf's motion library: the dog's motions, re-keyed onto Rigify's wolf (§6.1).

Rigify's wolf (``rigify_wolf``, evaluated by Blender) is the same animal as the
built-in dog, about ``LENGTH_SCALE`` times its size, so it gets the same motions
rather than a second set of designs: each clip is the quadruped's own motion
(:mod:`.quadruped`, keyed by its semantic :class:`~.quadruped.Dog` helpers) on a
stand-in builder that speaks the dog rig's control names, and :class:`DogToWolf`
then writes those curves onto the wolf's used controls — what a TD does to move
animation between two rigs with a mapping table. Train and test clips are the
dog's (the test clips carry the paper's Table 1 names); the seed, and so every
take, is the wolf's own.

How the mapping works (every wolf channel is keyed on the frames its dog
channels are keyed on, with their interpolation):

* lengths scale by ``LENGTH_SCALE``; axes turn from the dog's (rigmap axes: Y up,
  Z forward, +X the animal's left) into each wolf bone's own. The root, torso,
  hips, chest and IK paws translate along X left, Y back, Z up and rotate about
  those axes; head, neck and tail bones bend about X and turn about Z; FK leg bones
  hang down, their X axis flipped on the front legs;
* several dog channels may add onto one wolf channel: the dog's 12 tail joints
  onto the wolf's 4 tail bones, its heel roll and hock onto the wolf's heel;
* the wolf's torso pivots at its hips, the dog's COG mid-body: the torso's
  translation is corrected at each key (the full rotation is known there) so the
  body turns about a point ``PIVOT_FORWARD`` ahead of the hips — a sit lowers
  them, though less than the dog's (the wolf's longer hind legs need the room);
* the dog's tail wave (a travelling sine, a feature of the dog rig) is sampled
  every ``WAVE_STEP`` frames onto the tail bones' side bend;
* wolf controls without a dog counterpart (IK stretch, neck and tail follow, heel
  twist, a hip shift) get a small seeded settle on the clip's first, middle and
  last keyed frame, like the dog's own ``carriage`` pass;
* the dog's ears, eyes and jaw are not used controls of the wolf: dropped.

Conventions were measured on the generated rig by moving one control at a time
(positions in cm, COG-relative offsets world-aligned, Y up).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from rigmap.animation.library import quadruped as dog
from rigmap.animation.library.clip_builder import ClipBuilder
from rigmap.animation.library.rekey import (
    CurveRekeyer,
    SettleChannel,
    Term,
    library_through_stand_in,
    rest_value,
)

#: wolf cm per dog cm: COG heights 79.3 / 60 cm, paw spans 66 / 55 cm
LENGTH_SCALE = 1.3
#: where the wolf's torso control sits at rest (cm, world): above the hip joints
WOLF_TORSO_REST_Z = -32.5
#: the wolf's body turns about a point this far forward of its torso (cm): half way to where
#: the dog's COG pivot lands on the wolf. The dog's own pivot would sit the wolf's hips as low
#: as the dog's, which its longer hind legs (knees that do not splay) cannot fold under.
PIVOT_FORWARD = 0.5 * (LENGTH_SCALE * dog.COG_REST_Z - WOLF_TORSO_REST_Z)
#: nominal frames between samples of the dog's tail wave
WAVE_STEP = 2.0

WAVE_SOURCES = ("tail.wave_amplitude", "tail.wave_phase")
WOLF_SIDE = {"l": "L", "r": "R"}
TAIL_BONES = ("spine.003", "spine.002", "spine.001", "spine")  # base to tip
TAIL_MASTER = "spine_master.003"
TAIL_MASTER_SHARE = 0.25  # of the dog's curl and side curl; the bones take the rest
#: spine FK tweaks: share of the dog's mid-spine arch/side bend, and which end they move
SPINE_TWEAKS = {
    "spine_fk.004": (0.4, -1.0),
    "spine_fk.005": (0.6, -1.0),
    "spine_fk.006": (0.5, 1.0),
    "spine_fk.007": (0.3, 1.0),
    "spine_fk.008": (0.2, 1.0),
}
ARCH_PER_CM = 0.04  # rad of tweak bend per dog cm of mid-spine displacement
TWIST_SHARE = 0.3  # of the dog's hip/chest roll given to the tweaks as twist
HOCK_SHARE = 0.55  # of the dog's hock fold given to the wolf's heel (its hock lies lower)
PAW_FLEX_SHARE = 0.6  # of the dog's paw flex: the wolf's IK paw turns about its heel pad
POLE_TWIST_PER_CM = 0.02  # rad of knee direction per dog cm of pole offset
TOE_CURL_SHARE = 0.3  # rad of toe bend per unit of the dog's toe curl / spread

#: dog controls whose rest value is not 0 (checked against the rig by the tests)
DOG_DEFAULTS = {"ik_fk": 1.0, "follow": 1.0}
#: wolf controls whose rest value is not 0 (checked against the rig by the tests)
WOLF_DEFAULTS = {"IK_Stretch": 1.0, "neck_follow": 0.5}


@dataclass(frozen=True)
class WolfChannel:
    """One wolf control: its rest value plus weighted dog channels (plus the tail wave)."""

    target: str
    terms: tuple[Term, ...]
    wave_joints: tuple[int, ...] = ()  # dog tail joints (0-based) whose wave adds here


def _channel(target: str, *terms: tuple[str, float], wave: Iterable[int] = ()) -> WolfChannel:
    return WolfChannel(target, tuple(Term(s, w) for s, w in terms), tuple(wave))


# --- the mapping table ------------------------------------------------------------------------
def _body_channels() -> list[WolfChannel]:
    k = LENGTH_SCALE
    channels = [
        # the root: the wolf's ground-plane placement (tx, ty) and heading (rz)
        _channel("root.tx", ("root.tx", k)),
        _channel("root.ty", ("root.tz", -k)),
        _channel("root.rz", ("root.ry", 1.0)),
        _channel("hips.rx", ("hips.rx", 1.0)),
        _channel("hips.ry", ("hips.rz", -1.0)),
        _channel("hips.rz", ("hips.ry", 1.0)),
        _channel("chest.rx", ("chest.rx", 1.0)),
        _channel("chest.ry", ("chest.rz", -1.0)),
        _channel("chest.rz", ("chest.ry", 1.0)),
        _channel("chest.tx", ("chest.tx", k)),
        _channel("chest.ty", ("chest.tz", -k)),
        _channel("chest.tz", ("chest.ty", k)),
        # the dog's three neck joints onto the wolf's neck; its head follow onto the torso's
        _channel("neck.rx", *((f"neck_{j}_fk.rx", 1.0) for j in (1, 2, 3))),
        _channel("neck.ry", *((f"neck_{j}_fk.rz", 1.0) for j in (1, 2, 3))),
        _channel("neck.rz", *((f"neck_{j}_fk.ry", -1.0) for j in (1, 2, 3))),
        _channel("head.rx", ("head.rx", 1.0)),
        _channel("head.ry", ("head.rz", 1.0)),
        _channel("head.rz", ("head.ry", -1.0)),
        _channel("torso.head_follow", ("head.follow", -1.0)),
    ]
    for bone, (share, end) in SPINE_TWEAKS.items():
        roll = "hips.rz" if end < 0 else "chest.rz"
        channels += [
            _channel(f"{bone}.rx", ("spine_mid.ty", end * ARCH_PER_CM * share)),
            _channel(f"{bone}.ry", (roll, -TWIST_SHARE * share)),
            _channel(f"{bone}.rz", ("spine_mid.tx", end * ARCH_PER_CM * share)),
        ]
    return channels


def _tail_channels() -> list[WolfChannel]:
    """The dog's 12 FK joints, curl and wave onto the wolf's 4 tail bones and tail master."""
    per_bone = dog.TAIL // len(TAIL_BONES)
    bone_curl = (1.0 - TAIL_MASTER_SHARE) / len(TAIL_BONES)
    channels = [
        _channel(f"{TAIL_MASTER}.rx", ("tail.curl", TAIL_MASTER_SHARE)),
        _channel(f"{TAIL_MASTER}.rz", ("tail.side_curl", TAIL_MASTER_SHARE)),
    ]
    for g, bone in enumerate(TAIL_BONES):
        joints = range(g * per_bone + 1, (g + 1) * per_bone + 1)
        sway = [(f"tail_{j}_fk.ry", 1.0) for j in joints]
        channels += [
            _channel(
                f"{bone}.rx", ("tail.curl", bone_curl), *((f"tail_{j}_fk.rx", 1.0) for j in joints)
            ),
            _channel(
                f"{bone}.rz",
                ("tail.side_curl", bone_curl),
                *sway,
                wave=[j - 1 for j in joints],
            ),
            # a little twist with the sway, as the bones turn
            _channel(f"{bone}.ry", *((s, 0.2 * w) for s, w in sway)),
        ]
    return channels


def _leg_channels(leg: str) -> list[WolfChannel]:
    """One dog leg (``front_leg_l`` ...) onto the wolf's leg of the same end and side."""
    k = LENGTH_SCALE
    end, side = leg.split("_")[0], leg.rsplit("_", 1)[1]
    s = WOLF_SIDE[side]
    sign = dog.SIDES[side]
    front = end == "front"
    wolf = "front_" if front else ""
    ik, heel = f"{wolf}foot_ik.{s}", f"{wolf}foot_heel_ik.{s}"
    toe = f"{wolf}toe.{s}"
    source_ik = f"{leg}_ik"
    channels = [
        _channel(f"{ik}.tx", (f"{source_ik}.tx", k)),
        _channel(f"{ik}.ty", (f"{source_ik}.tz", -k)),
        _channel(f"{ik}.tz", (f"{source_ik}.ty", k)),
        _channel(f"{ik}.rx", (f"{source_ik}.rx", -PAW_FLEX_SHARE)),
        _channel(f"{ik}.ry", (f"{source_ik}.ry", 1.0)),
        _channel(f"{ik}.rz", (f"{source_ik}.rz", -1.0)),
        # the heel peels the paw (roll) and, on the hind leg, folds the hock down to sit
        _channel(
            f"{heel}.rx",
            (f"{leg}.roll", -1.0 if front else 1.0),
            *(() if front else ((f"{leg}_hock.rx", HOCK_SHARE),)),
        ),
        _channel(f"{heel}.rz", (f"{leg}.bank", (-1.0 if front else 1.0) * sign)),
        # the pole's sideways offset turns the knee
        _channel(
            f"{wolf}thigh_ik.{s}.ry",
            (f"{leg}_pole.tx", (1.0 if front else -1.0) * POLE_TWIST_PER_CM),
        ),
        _channel(f"{wolf}thigh_parent.{s}.IK_FK", (f"{leg}.ik_fk", -1.0)),
    ]
    # toes: the dog's toe tap, FK paw bend, curl and spread onto the wolf's one toe control
    toes = f"{end}_toe_{side}"
    channels += [
        _channel(
            f"{toe}.rx",
            (f"{leg}.toe_tap", 1.0),
            (f"{dog.FK_JOINTS[end][-1]}_{side}_fk.rx", -1.0),
            (f"{toes}s.curl", -TOE_CURL_SHARE),
        ),
        _channel(f"{toe}.ry", (f"{toes}s.side_curl", sign * TOE_CURL_SHARE)),
        _channel(
            f"{toe}.rz",
            (f"{toes}_1_fk.rx", TOE_CURL_SHARE),
            (f"{toes}_4_fk.rx", -TOE_CURL_SHARE),
        ),
    ]
    # FK: thigh/upper arm, shin/forearm, foot/wrist hang down; the front bones' X is flipped
    wolf_fk = (
        ("front_thigh_fk", "front_shin_fk", "front_foot_fk")
        if front
        else (
            "thigh_fk",
            "shin_fk",
            "foot_fk",
        )
    )
    flips = {"rx": -1.0, "ry": -1.0, "rz": 1.0} if front else {"rx": 1.0, "ry": -1.0, "rz": -1.0}
    for source, target in zip(dog.FK_JOINTS[end][:3], wolf_fk, strict=True):
        for axis, flip in flips.items():
            channels.append(_channel(f"{target}.{s}.{axis}", (f"{source}_{side}_fk.{axis}", flip)))
    if front:
        scapula = f"scapula_{side}_ctrl"
        channels += [
            _channel(f"shoulder.{s}.rx", (f"{scapula}.rx", 1.0)),
            _channel(f"shoulder.{s}.ry", (f"{scapula}.ry", 1.0)),
            _channel(f"shoulder.{s}.rz", (f"{scapula}.rz", -1.0)),
        ]
    return channels


def _settle_channels() -> list[SettleChannel]:
    k = LENGTH_SCALE
    channels = [
        SettleChannel("torso.tail_follow", 0.5, 0.4, 0.0, 1.0),
        SettleChannel("torso.neck_follow", 0.5, 0.3, 0.0, 1.0),
        *(SettleChannel(f"hips.t{axis}", 0.0, 1.0 * k) for axis in "xyz"),
    ]
    for s in WOLF_SIDE.values():
        for wolf in ("front_", ""):
            channels += [
                SettleChannel(f"{wolf}thigh_parent.{s}.IK_Stretch", 0.9, 0.1, 0.0, 1.0),
                SettleChannel(f"{wolf}foot_heel_ik.{s}.ry", 0.0, 0.1),
            ]
    return channels


CHANNELS: tuple[WolfChannel, ...] = (
    *_body_channels(),
    *_tail_channels(),
    *(channel for leg in dog.LEGS for channel in _leg_channels(leg)),
)
SETTLE_CHANNELS: tuple[SettleChannel, ...] = tuple(_settle_channels())
TORSO_CHANNELS = tuple(f"torso.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz"))
DOG_COG = tuple(f"cog.{c}" for c in ("tx", "ty", "tz", "rx", "ry", "rz"))


def wolf_controls() -> list[str]:
    """Every wolf control the library keys (all of them the wolf's used controls)."""
    return [
        *TORSO_CHANNELS,
        *(c.target for c in CHANNELS),
        *(c.target for c in SETTLE_CHANNELS),
    ]


# --- re-keying --------------------------------------------------------------------------------
class DogToWolf(CurveRekeyer):
    """Writes a dog motion's nominal curves onto a wolf clip builder."""

    source_defaults = DOG_DEFAULTS

    def key_onto(self, b: ClipBuilder) -> None:
        self._torso(b)
        for channel in CHANNELS:
            self._channel(b, channel)
        self._settle(b, SETTLE_CHANNELS)

    # --- channels ---------------------------------------------------------------------------
    def _channel(self, b: ClipBuilder, channel: WolfChannel) -> None:
        sources = [t.source for t in channel.terms]
        waving = bool(channel.wave_joints) and any(s in self.curves for s in WAVE_SOURCES)
        frames = self._frames([*sources, *(WAVE_SOURCES if waving else ())])
        if frames.size == 0:
            return
        if waving:  # a sine is not a curve through its keys: sample it (Bézier between)
            dense = np.arange(frames[0], frames[-1], WAVE_STEP)
            frames = np.unique(np.concatenate([frames, dense]))
        values = np.full(len(frames), rest_value(channel.target, WOLF_DEFAULTS))
        for term in channel.terms:
            values += term.weight * self._value(term.source, frames)
        if waving:
            values += self._wave(channel.wave_joints, frames)
        self._write(b, channel.target, sources, frames, values)

    def _wave(self, joints: tuple[int, ...], frames: np.ndarray) -> np.ndarray:
        """The dog's tail wave on these joints (its rig: amplitude × sin(2π i / 12 + phase))."""
        amplitude = self._value("tail.wave_amplitude", frames)
        phase = self._value("tail.wave_phase", frames)
        return sum(amplitude * np.sin(2 * math.pi * i / dog.TAIL + phase) for i in joints)

    def _torso(self, b: ClipBuilder) -> None:
        """The dog's COG onto the wolf's torso, turning about the dog's pivot (mid-body)."""
        frames = self._frames(DOG_COG)
        if frames.size == 0:
            return
        tx, ty, tz, rx, ry, rz = (self._value(s, frames) for s in DOG_COG)
        rotation = {"rx": rx, "ry": -rz, "rz": ry}  # wolf Euler XYZ about X left, Y back, Z up
        turned = torso_rotation(rotation["rx"], rotation["ry"], rotation["rz"])
        pivot = np.array([0.0, 0.0, PIVOT_FORWARD])
        offset = LENGTH_SCALE * np.stack([tx, ty, tz], axis=1) + pivot - turned @ pivot
        local = {"tx": offset[:, 0], "ty": -offset[:, 2], "tz": offset[:, 1]}
        for name in TORSO_CHANNELS:
            axis = name.rsplit(".", 1)[1]
            values = local[axis] if axis.startswith("t") else rotation[axis]
            self._write(b, name, DOG_COG, frames, values)


def torso_rotation(rx, ry, rz) -> np.ndarray:
    """``(N, 3, 3)`` rotations in rigmap axes of the torso's Euler XYZ angles (radians).

    The torso's own axes are X left, Y back, Z up; Blender's XYZ order turns about
    X first, then Y, then Z (``R = Rz Ry Rx`` in the bone's axes).
    """
    rx, ry, rz = (np.atleast_1d(np.asarray(a, dtype=np.float64)) for a in (rx, ry, rz))
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    one, zero = np.ones_like(rx), np.zeros_like(rx)
    Rx = np.stack([one, zero, zero, zero, cx, -sx, zero, sx, cx], -1).reshape(-1, 3, 3)
    Ry = np.stack([cy, zero, sy, zero, one, zero, -sy, zero, cy], -1).reshape(-1, 3, 3)
    Rz = np.stack([cz, -sz, zero, sz, cz, zero, zero, zero, one], -1).reshape(-1, 3, 3)
    axes = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # columns: X, Y, Z
    return axes @ Rz @ Ry @ Rx @ axes.T


LIBRARY = library_through_stand_in("rigify_wolf", dog.LIBRARY, DogToWolf)
