"""The dog's motion library: everyday training clips and three held-out test clips (§6.1).

Keys go on the quadruped rig's used controls as an animator would set them: IK paws
planted in root space while the body travels, heel peel through ``roll`` before a
paw lifts, overlap on tail and ears, legs switched to FK (``*.ik_fk``) when they
leave the ground to scratch, give a paw or stretch out lying down. Test clips
("Jumping & Playing", "Turning & Galloping", "Begging Excitedly", the paper's
Table 1) are larger, faster and more extreme than anything in training.

Conventions of the rig (centimetres, radians): the dog faces +Z, +X is its left, Y
is up. Translations of IK paws, poles and the COG are offsets from their rest
places; ``rx`` > 0 pitches a part nose-down (and swings a leg backwards), ``ry`` > 0
turns the nose to the dog's left. Controls of the right side mirror the left ones:
``tx``, ``ry`` and ``rz`` change sign, so the helpers below take left-side values.
"""

from __future__ import annotations

import math

import numpy as np

from rigmap.animation.library import Clips
from rigmap.animation.library.body import SIDES, BodyKeys
from rigmap.animation.library.clip_builder import ClipBuilder

FRONT = ("front_leg_l", "front_leg_r")
HIND = ("hind_leg_l", "hind_leg_r")
LEGS = FRONT + HIND
FK_JOINTS = {
    "front": ("upper_arm", "forearm", "wrist", "front_paw"),
    "hind": ("thigh", "stifle", "hock", "hind_paw"),
}
TAIL = 12
NECK = 3
# rest positions (cm) of what the turning helper rotates about
COG_REST_Z = -3.0
PAW_REST_XZ = {"front_leg": (8.0, 20.0), "hind_leg": (8.0, -31.0)}


def _side(leg: str) -> str:
    return leg.rsplit("_", 1)[1]


def _other_side(leg: str) -> str:
    base, side = leg.rsplit("_", 1)
    return f"{base}_{'r' if side == 'l' else 'l'}"


def _end(leg: str) -> str:
    return "front" if leg.startswith("front") else "hind"


class Dog(BodyKeys):
    """Semantic keying on top of a :class:`ClipBuilder`: paws, legs, spine, head, tail."""

    # --- raw -------------------------------------------------------------------
    def key(self, frame: float, interpolation: str = "bezier", **values: float) -> None:
        """Key controls given as ``control__channel=value`` (``cog__ty=-3``)."""
        self.b.pose(frame, {k.replace("__", "."): v for k, v in values.items()}, interpolation)

    # --- legs --------------------------------------------------------------------
    def paw(self, frame: float, leg: str, interpolation: str = "bezier", **channels) -> None:
        """IK paw control of ``leg`` (tx ty tz rx ry rz), left-side convention."""
        self._mirrored(f"{leg}_ik", _side(leg), channels, frame, interpolation)

    def plant(self, leg: str, start: float, end: float, tx: float, ty: float, tz: float) -> None:
        """The IK paw stays put from ``start`` to ``end`` (in root space)."""
        self._hold(f"{leg}_ik", _side(leg), start, end, tx, ty, tz)

    def leg(self, frame: float, leg: str, interpolation: str = "bezier", **attributes) -> None:
        """Leg attributes: ``roll``, ``bank``, ``toe_tap``, ``ik_fk``, ``hock`` (hind only)."""
        for name, value in attributes.items():
            control = f"{leg}_hock.rx" if name == "hock" else f"{leg}.{name}"
            self.b.key(control, frame, value, interpolation)

    def pole(self, frame: float, leg: str, **channels) -> None:
        self._mirrored(f"{leg}_pole", _side(leg), channels, frame, "bezier")

    def fk(self, frame: float, joint: str, side: str, **channels) -> None:
        """FK rotation of a leg joint (``upper_arm``, ``thigh``, ...), left-side convention."""
        self._mirrored(f"{joint}_{side}_fk", side, channels, frame, "bezier")

    def fk_leg(self, frame: float, leg: str, angles, looseness: float = 0.04) -> None:
        """The whole FK leg at once: ``angles`` = one (rx, ry, rz) per joint, top down.

        Below the top joint each twist and side bend gets a seeded wobble of up to
        ``looseness`` radians: hand-set FK poses are never exactly planar.
        """
        self._fk_joints(frame, FK_JOINTS[_end(leg)], _side(leg), angles, looseness)

    def toes(self, frame: float, leg: str, curl: float, spread: float, each=None) -> None:
        side = _side(leg)
        prefix = f"{_end(leg)}_toe_{side}"
        self.b.key(f"{prefix}s.curl", frame, curl)
        self.b.key(f"{prefix}s.side_curl", frame, spread)
        for k, value in enumerate(each if each is not None else (0.0,) * 4):
            self.b.key(f"{prefix}_{k + 1}_fk.rx", frame, value)

    # --- body, head, tail ------------------------------------------------------------
    def neck(self, frame: float, rx: float = 0.0, ry: float = 0.0, rz: float = 0.0) -> None:
        """Bend spread over the three neck joints (totals, radians)."""
        for k, weight in enumerate((0.4, 0.33, 0.27)):
            self.key(
                frame,
                **{
                    f"neck_{k + 1}_fk__rx": weight * rx,
                    f"neck_{k + 1}_fk__ry": weight * ry,
                    f"neck_{k + 1}_fk__rz": weight * rz,
                },
            )

    def head(self, frame: float, rx=0.0, ry=0.0, rz=0.0, jaw=None, follow=None) -> None:
        self.key(frame, head__rx=rx, head__ry=ry, head__rz=rz)
        if jaw is not None:
            self.b.key("jaw_ctrl.rx", frame, jaw)
        if follow is not None:
            self.b.key("head.follow", frame, follow)

    def eyes(self, frame: float, tx: float = 0.0, ty: float = 0.0, tz: float = 0.0) -> None:
        self.key(frame, eye_aim__tx=tx, eye_aim__ty=ty, eye_aim__tz=tz)

    def ears(
        self, frame: float, side: str, curl=0.0, side_curl=0.0, rx=0.0, rz=0.0, wave=None
    ) -> None:
        """Ear pose; ``rx`` > 0 folds it forward, ``rz`` > 0 flops it outward (both sides)."""
        sign = SIDES[side]
        self.b.key(f"ear_{side}.curl", frame, curl)
        self.b.key(f"ear_{side}.side_curl", frame, side_curl)
        for k, weight in enumerate((0.5, 0.3, 0.2)):
            self.b.key(f"ear_{k + 1}_{side}_fk.rx", frame, weight * rx)
            self.b.key(f"ear_{k + 1}_{side}_fk.rz", frame, -sign * weight * rz)
        if wave is not None:
            amplitude, phase = wave
            self.b.key(f"ear_{side}.wave_amplitude", frame, amplitude)
            self.b.key(f"ear_{side}.wave_phase", frame, phase)

    def tail(
        self, frame: float, curl=0.0, side_curl=0.0, lift=0.0, sway=0.0, lag=0.0, phase=0.0, tip=0.0
    ) -> None:
        """Tail: ``curl``/``side_curl`` attributes plus per-joint FK.

        ``lift`` raises the base (rx on the first joints), ``tip`` hooks the far half up
        (> 0) or down, ``sway`` swings it sideways as a wave travelling down the tail:
        joint k lags ``lag`` radians behind.
        """
        self.key(frame, tail__curl=curl, tail__side_curl=side_curl)
        for k in range(TAIL):
            base = max(0.0, 1.0 - k / 4.0)
            hook = max(0.0, (k - 3.0) / (TAIL - 4.0))
            self.b.key(f"tail_{k + 1}_fk.rx", frame, lift * base + 0.25 * tip * hook)
            self.b.key(f"tail_{k + 1}_fk.ry", frame, sway / TAIL * 2.0 * math.sin(phase - lag * k))

    def tail_wave(
        self, frame: float, amplitude: float, phase: float, interpolation: str = "bezier"
    ) -> None:
        self.b.key("tail.wave_amplitude", frame, amplitude)
        self.b.key("tail.wave_phase", frame, phase, interpolation)

    # --- the polish pass ------------------------------------------------------------------
    def carriage(self, frames, alert: float = 0.0) -> None:
        """Secondary controls an animator sets per shot: ears, toes, poles, eye line.

        Seeded, small, and different on each listed frame (a settle, a twitch);
        ``alert`` > 0 perks the ears up and forward. Controls the motion already
        animates are left alone, so call this last.
        """
        b = self.b

        def key_frame(dog: Dog, frame: float) -> None:
            for side in SIDES:
                dog.ears(
                    frame,
                    side,
                    curl=b.vary(0.1 + 0.3 * alert, 0.25),
                    side_curl=b.vary(0.0, 0.2),
                    rx=b.vary(0.25 * alert, 0.2),
                    rz=b.vary(0.15 - 0.3 * alert, 0.15),
                )
            for leg in LEGS:
                dog.toes(
                    frame,
                    leg,
                    curl=b.vary(0.1, 0.12),
                    spread=b.vary(0.05, 0.1),
                    each=[b.vary(0.0, 0.08) for _ in range(4)],
                )
                dog.pole(frame, leg, tx=b.vary(1.5, 2.0), ty=b.vary(0.0, 2.0), tz=b.vary(0.0, 3.0))
            dog.eyes(frame, b.vary(0.0, 15.0), b.vary(-5.0, 8.0), b.vary(0.0, 10.0))

        self._polish(frames, key_frame)


# this library's clip functions, in corpus order (see rigmap.animation.library.Clips)
clips = Clips()


# --- gaits ----------------------------------------------------------------------------------
def _stepping(
    dog: Dog, leg: str, plants, swings, *, height: float, flex: float, peel: float
) -> None:
    """Key a paw through alternating plants and swings.

    ``plants``: list of (start, end, (tx, tz)) held on the ground (ty 0);
    ``swings``: list of (lift, land, peak) between consecutive plants, peak = the
    frame the paw is highest. Before each lift the heel peels (``roll``) while the
    paw is still planted; in the air the paw flexes (``rx``) and the toes curl.
    """
    for start, end, (tx, tz) in plants:
        dog.plant(leg, start, end, tx, 0.0, tz)
        dog.paw(start, leg, rx=0.0)
        dog.leg(start, leg, roll=0.0)
    for (lift, land, peak), (_, _, (tx0, tz0)), (_, _, (tx1, tz1)) in zip(
        swings, plants[:-1], plants[1:], strict=True
    ):
        share = (peak - lift) / (land - lift)
        dog.paw(
            peak,
            leg,
            tx=tx0 + 0.55 * (tx1 - tx0),
            ty=height,
            tz=tz0 + (0.25 + 0.5 * share) * (tz1 - tz0),
            rx=flex,
        )
        dog.leg(lift, leg, roll=peel)
        dog.leg(peak, leg, roll=0.2 * peel)
        dog.leg(land, leg, roll=0.0)
        dog.paw(lift, leg, rx=0.0)
        dog.paw(land, leg, rx=0.0)


def _gait_plants(lifts, swing: float, period: float, position, first: float, last: float):
    """Plants and swings of one leg from its lift times and the body's path.

    Each new plant is centred on where the body will be at mid-stance, clamped to
    ``[first, last]`` (the standing start and the final stop).
    """
    plants, swings = [], []
    start, place = -math.inf, first
    for lift in lifts:
        if place >= last - 1e-9:
            break
        land = lift + swing
        mid_stance = land + 0.5 * (period - swing)
        target = min(max(position(mid_stance), first), last)
        plants.append((start, lift, place))
        swings.append((lift, land))
        start, place = land, target
    plants.append((start, math.inf, place))
    return plants, swings


@clips.train("Walk", "two strides of a lateral-sequence walk, starting and stopping")
def walk(b: ClipBuilder) -> None:
    """Stand, walk two strides forward with a lateral-sequence gait, stop and settle.

    The root stays put; the COG and the paws travel in root space. Each paw is planted
    (constant) while the body passes over it, peels its heel, swings and lands.
    """
    dog = Dog(b)
    period, swing, peak = 24.0, 9.0, 3.0
    stride = b.vary(24.0, 3.0)
    lower = b.vary(1.5, 0.8)
    z0, z1 = -stride, stride
    t0 = 6.0
    cycles = 2
    t1 = t0 + cycles * period
    speed = (z1 - z0) / (t1 - t0)

    def body(t):
        return z0 + speed * (t - t0)

    phases = {"hind_leg_l": 0.0, "front_leg_l": 6.0, "hind_leg_r": 12.0, "front_leg_r": 18.0}
    heights = {"front": b.vary(9.0, 1.5), "hind": b.vary(8.0, 1.5)}
    last_land = t0
    for leg, phase in phases.items():
        lifts = [t0 + phase + k * period for k in range(cycles + 2)]
        plants, swings = _gait_plants(lifts, swing, period, body, z0, z1)
        end = max(s[1] for s in swings) + 12.0
        last_land = max(last_land, end)
        plants = [
            (0.0 if s == -math.inf else s, end if e == math.inf else e, (0.0, z))
            for s, e, z in plants
        ]
        swings = [(lift, land, lift + peak) for lift, land in swings]
        _stepping(
            dog,
            leg,
            plants,
            swings,
            height=heights[_end(leg)],
            flex=b.vary(0.9 if _end(leg) == "front" else 0.6, 0.15),
            peel=b.vary(0.45, 0.1),
        )
    end = last_land
    # body: eases from standing into a steady pace, bobbing twice a cycle, and settles
    dog.cog(0.0, tz=z0, ty=0.0)
    bob = b.vary(1.2, 0.4)
    for k in range(cycles * 4 + 1):
        t = t0 + 6.0 * k
        dog.cog(
            t,
            "linear" if 0 < k < cycles * 4 else "bezier",
            tz=body(t),
            ty=-lower - (bob if k % 2 == 0 else 0.0),
            rz=0.03 * (1 if k % 4 == 0 else -1 if k % 4 == 2 else 0),
        )
        roll = 0.06 * (1 if k % 4 in (0, 1) else -1)
        yaw = 0.05 * (1 if k % 4 in (1, 2) else -1)
        dog.spine(t, hips=(0.0, yaw, roll), chest=(0.02, -yaw, -roll))
        dog.neck(t, rx=b.vary(0.05, 0.05) + (0.06 if k % 2 else -0.04), ry=b.vary(0.0, 0.1))
        dog.head(t, rx=(-0.05 if k % 2 else 0.04), ry=b.vary(0.0, 0.08))
        dog.tail(
            t,
            curl=b.vary(0.3, 0.15),
            tip=b.vary(-0.1, 0.15),
            side_curl=0.25 * (1 if k % 4 < 2 else -1),
            lift=b.vary(0.05, 0.05),
            sway=0.3,
            lag=0.6,
            phase=math.pi / 2 * k,
        )
    dog.cog(end, tz=z1, ty=0.0, rz=0.0)
    dog.spine(end)
    dog.neck(end, rx=b.vary(0.0, 0.1))
    dog.head(end)
    dog.tail(end, curl=0.25, lift=0.05)
    dog.carriage([0.0, t0 + period, end])


@clips.train("Trot", "four trot cycles along a gentle curve, root travelling")
def trot(b: ClipBuilder) -> None:
    """Four cycles of a trot along a gentle curve; the root travels.

    Diagonal pairs (left fore + right hind, right fore + left hind) swing together. The
    root moves at the trot's speed, so a paw on the ground slides back in root space at
    exactly that speed (linear keys on the same frames as the root's) and stays put in
    the world.
    """
    dog = Dog(b)
    period, swing, grid = 16.0, 8.0, 4.0
    cycles = 4
    stride = b.vary(48.0, 6.0)
    reach = 0.25 * stride  # a stance (half a cycle) sweeps half a stride
    turn_ = b.vary(0.25, 0.2) * b.sign()
    end = cycles * period + swing

    def heading(t):
        return turn_ * t / end

    # the root along an arc, keyed on every beat so paws and root share their timing
    x, z = b.vary(0.0, 20.0), -110.0
    beats = np.arange(0.0, end + 1e-9, grid)
    for i, t in enumerate(beats):
        if i:
            h = heading(t - 0.5 * grid)
            x += stride / period * grid * math.sin(h)
            z += stride / period * grid * math.cos(h)
        dog.root(
            float(t), "linear" if 0 < i < len(beats) - 1 else "bezier", tx=x, tz=z, ry=heading(t)
        )
    height = {"front": b.vary(9.0, 2.0), "hind": b.vary(7.0, 2.0)}
    flex = {"front": b.vary(0.9, 0.15), "hind": b.vary(0.6, 0.15)}
    pairs = {"front_leg_l": 0.0, "hind_leg_r": 0.0, "front_leg_r": 8.0, "hind_leg_l": 8.0}
    for leg, phase in pairs.items():
        for k in range(-1, cycles + 1):
            lift = phase + k * period
            peak, land = lift + grid, lift + swing
            if 0.0 <= lift <= end:
                # end of a stance, start of a swing
                b.key(f"{leg}_ik.tz", lift, -reach, "bezier")
                b.key(f"{leg}_ik.ty", lift, 0.0, "bezier")
                dog.leg(lift, leg, roll=b.vary(0.4, 0.1))
                dog.paw(lift, leg, rx=0.0)
                if lift - grid >= 0.0:
                    dog.leg(lift - grid, leg, roll=0.0)
            if 0.0 <= peak <= end:
                dog.paw(peak, leg, ty=height[_end(leg)], tz=0.0, rx=flex[_end(leg)])
                dog.leg(peak, leg, roll=0.1)
                dog.toes(peak, leg, curl=b.vary(0.5, 0.1), spread=0.0)
            if 0.0 <= land <= end:
                # footfall: the stance slides linearly back in root space
                b.key(f"{leg}_ik.tz", land, reach, "linear")
                b.key(f"{leg}_ik.ty", land, 0.0, "linear")
                dog.paw(land, leg, rx=0.0)
                dog.toes(land, leg, curl=0.05, spread=0.1)
                if land + grid <= end:
                    b.key(f"{leg}_ik.tz", land + grid, 0.0, "linear")
                    b.key(f"{leg}_ik.ty", land + grid, 0.0, "linear")
    # body: bob at each footfall, roll with the diagonal, head and ears bounce
    for k, t in enumerate(beats):
        t = float(t)
        low = k % 2 == 1  # mid-stance
        swing_side = 1 if k % 4 < 2 else -1
        dog.cog(
            t,
            ty=b.vary(-2.0, 0.5) - (1.5 if low else 0.0),
            tz=0.0,
            rz=0.04 * (1 if k % 4 == 1 else -1 if k % 4 == 3 else 0),
            rx=b.vary(0.03, 0.02),
        )
        dog.spine(
            t,
            hips=(0.0, 0.04 * swing_side, 0.05 * swing_side),
            chest=(0.0, -0.04 * swing_side, -0.05 * swing_side),
            mid=(0.0, -1.0 if low else 0.5, 0.0),
        )
        dog.head(t, rx=-0.08 if low else 0.02, ry=-0.5 * heading(t))
        dog.neck(t, rx=0.12 if low else 0.05, ry=0.4 * turn_)
        for side in SIDES:
            dog.ears(
                t,
                side,
                curl=0.3 if low else -0.1,
                rx=-0.3 if low else 0.1,
                rz=0.25,
                wave=(0.2, (1.2 * k) % (2 * math.pi) - math.pi),
            )
        dog.tail(
            t,
            curl=0.45,
            side_curl=0.3 * swing_side,
            lift=0.1,
            tip=0.2,
            sway=0.5,
            lag=0.5,
            phase=k * math.pi / 2,
        )
    dog.eyes(0.0, tx=20.0 * turn_, ty=-10.0)
    dog.eyes(end, tx=30.0 * turn_, ty=-10.0)


# --- sitting, lying ---------------------------------------------------------------------------
SIT = {"cog": dict(ty=-27.0, tz=-14.0, rx=-0.9), "hock": -1.08, "front_tz": -9.0}


def _sit_body(dog: Dog, frame: float, amount: float, b: ClipBuilder, *, pitch: float = 1.0):
    """The body part of a sit at ``amount`` (0 stand .. 1 sit)."""
    cog = SIT["cog"]
    dog.cog(frame, ty=amount * cog["ty"], tz=amount * cog["tz"], rx=amount * pitch * cog["rx"])
    for leg in HIND:
        dog.leg(frame, leg, hock=amount * SIT["hock"])
        dog.pole(frame, leg, tx=amount * b.vary(6.0, 2.0), tz=amount * 10.0)
    dog.spine(frame, hips=(amount * 0.3, 0.0, 0.0), chest=(amount * 0.15, 0.0, 0.0))
    dog.neck(frame, rx=amount * 0.45)
    dog.head(frame, rx=amount * 0.4)


def _sitting_tail(dog: Dog, frame: float, amount: float, side_curl: float = 0.0) -> None:
    """Tail lifted at the base against the pitched pelvis, lying along the floor."""
    dog.tail(
        frame, curl=0.3 - 0.8 * amount, lift=0.25 * amount, tip=0.2 * amount, side_curl=side_curl
    )


@clips.train("Sit Down & Stand Up", "sits, tilts its head, stands")
def sit_down_stand_up(b: ClipBuilder) -> None:
    """Sit down, look about while sitting, stand back up."""
    dog = Dog(b)
    sit_at, up_at, end = 26.0, 72.0, 96.0
    for t, amount in (
        (0.0, 0.0),
        (8.0, 0.05),
        (18.0, 0.7),
        (sit_at, 1.0),
        (up_at, 1.0),
        (84.0, 0.35),
        (end, 0.0),
    ):
        _sit_body(dog, t, amount, b)
    # front paws step back as the weight goes onto the haunches, and forward again
    back = SIT["front_tz"]
    for i, leg in enumerate(FRONT):
        down, up = 14.0 + 4.0 * i, 76.0 + 4.0 * i
        plants = [
            (0.0, down, (0.0, 0.0)),
            (down + 6.0, up, (0.0, back)),
            (up + 6.0, end, (0.0, 0.0)),
        ]
        swings = [(down, down + 6.0, down + 2.0), (up, up + 6.0, up + 2.0)]
        _stepping(dog, leg, plants, swings, height=4.0, flex=0.5, peel=0.3)
    for leg in HIND:
        dog.plant(leg, 0.0, end, 0.0, 0.0, 0.0)
        dog.leg(0.0, leg, roll=0.0)
        dog.leg(sit_at, leg, roll=b.vary(-0.2, 0.1))
        dog.leg(end, leg, roll=0.0)
    # sitting: a head tilt at a sound, a glance, the tail sweeps the floor
    tilt = b.sign() * b.vary(0.35, 0.1)
    for t, (ry, rz, ears) in {
        36.0: (0.0, 0.0, 0.0),
        44.0: (0.2 * tilt, tilt, 1.0),
        54.0: (0.1 * tilt, 0.4 * tilt, 0.6),
        62.0: (-0.6 * tilt, 0.0, 0.3),
    }.items():
        dog.key(t, head__ry=ry, head__rz=rz, head__rx=0.4)
        dog.eyes(t, tx=ry * 60.0, ty=10.0 * ears)
        for side in SIDES:
            dog.ears(t, side, curl=0.4 * ears, rx=0.5 * ears, rz=-0.2 * ears)
    for t, amount in ((0.0, 0.0), (sit_at, 1.0), (up_at, 1.0), (end, 0.0)):
        _sitting_tail(dog, t, amount)
    for t in (40.0, 48.0, 56.0):
        dog.tail_wave(t, amplitude=0.15 if t != 48.0 else 0.3, phase=(t - 40.0) / 8.0 * 2.5 - 2.5)
    dog.carriage([0.0, sit_at, end], alert=0.3)


@clips.train("Lie Down", "sits and lies down, front legs in FK, rolls on a hip")
def lie_down(b: ClipBuilder) -> None:
    """Sit, then slide the front paws out and lie down (front legs in FK) and settle.

    The front legs switch to FK while sitting (the FK pose matched to where the IK
    legs stand), fold at the elbow and lay the forearms flat; the head sinks onto them.
    """
    dog = Dog(b)
    sit_at, fk_at, lie_at, end = 20.0, 32.0, 44.0, 100.0
    for t, amount in ((0.0, 0.0), (8.0, 0.1), (sit_at, 1.0)):
        _sit_body(dog, t, amount, b)
    # lying: body level and low, chest near the ground, leaning onto one hip
    lean = b.sign() * b.vary(0.12, 0.04)
    dog.cog(fk_at, ty=-29.0, tz=-10.0, rx=-0.5)
    dog.cog(lie_at, ty=-29.5, tz=-6.0, rx=0.0, rz=0.0)
    dog.cog(70.0, ty=-30.0, tz=-6.0, rx=0.02, rz=lean)
    dog.cog(end, ty=-30.0, tz=-6.0, rx=0.03, rz=1.2 * lean)
    dog.spine(fk_at, hips=(0.25, 0.0, 0.0), chest=(0.05, 0.0, 0.0))
    dog.spine(
        lie_at,
        hips=(0.15, 0.0, 0.0),
        chest=(-0.1, 0.0, 0.0),
        chest_t=(0.0, -1.0, 0.0),
        mid=(0.0, -3.0, 0.0),
    )
    dog.spine(
        end,
        hips=(0.1, 0.15, lean),
        chest=(-0.12, -0.1, 0.0),
        chest_t=(b.vary(1.0, 1.0), -1.5, 1.0),
        mid=(1.0, -3.0, -1.5),
    )
    for leg in HIND:
        dog.plant(leg, 0.0, fk_at, 0.0, 0.0, 0.0)
        dog.leg(lie_at, leg, hock=-1.35)
        dog.paw(lie_at, leg, tz=6.0, rz=0.0)
        dog.paw(end, leg, tz=7.0, rz=0.15 * (1 if (leg == "hind_leg_l") == (lean > 0) else -1))
        dog.leg(end, leg, toe_tap=b.vary(0.2, 0.1))
    # front legs: IK while sitting, then FK (matched to the sitting legs) to lie down
    for i, leg in enumerate(FRONT):
        switch = sit_at + 3.0 + 2.0 * i
        dog.plant(leg, 0.0, switch, 0.0, 0.0, 0.0)
        dog.leg(sit_at, leg, ik_fk=1.0)
        dog.leg(switch, leg, ik_fk=0.0)
        dog.leg(end, leg, ik_fk=0.0)
        dog.fk_leg(
            switch, leg, [(0.9, 0.0, 0.0), (-0.1, 0.0, 0.0), (0.05, 0.0, 0.0), (0.0, 0.0, 0.0)]
        )
        dog.fk_leg(
            fk_at, leg, [(0.6, 0.0, 0.02), (-0.9, 0.0, 0.0), (0.6, 0.0, 0.0), (0.1, 0.0, 0.0)]
        )
        fold = b.vary(-1.75, 0.08)
        dog.fk_leg(
            lie_at + 4.0 * i,
            leg,
            [(0.25, 0.05, 0.05), (fold, 0.05, 0.0), (1.2, 0.0, 0.05), (0.3, 0.0, 0.0)],
        )
        dog.fk_leg(
            end,
            leg,
            [
                (0.22, 0.1, 0.08 + 0.05 * i),
                (fold - 0.05, 0.1, 0.05),
                (1.25, 0.05, -0.1),
                (0.35, 0.05, 0.05),
            ],
        )
        dog.toes(lie_at, leg, curl=0.3, spread=0.3)
    # head: looks down as it lies, rests on the paws, one last look
    for t, (neck_rx, head_rx, head_ry) in {
        0.0: (0.0, 0.0, 0.0),
        lie_at: (0.3, 0.3, 0.0),
        60.0: (0.5, 0.45, 0.0),
        76.0: (0.65, 0.55, b.vary(0.2, 0.15)),
        end: (0.75, 0.5, 0.05),
    }.items():
        dog.neck(t, rx=neck_rx, rz=0.1 * head_ry)
        dog.head(t, rx=head_rx, ry=head_ry, jaw=0.02 if t < end else 0.0)
        dog.tail(
            t,
            curl=0.0 if t else 0.2,
            side_curl=1.4 * lean / 0.12 if t >= 60 else 0.0,
            lift=0.1 if t else 0.0,
            tip=-0.2 if t else 0.0,
        )
        for side in SIDES:
            dog.ears(t, side, curl=0.2, rz=0.4 if t >= 60 else 0.1, rx=-0.1)
    dog.eyes(0.0, ty=-10.0)
    dog.eyes(end, ty=-40.0, tx=10.0)
    dog.toes(0.0, "hind_leg_l", 0.1, 0.0)
    dog.toes(end, "hind_leg_l", 0.3, 0.2)


# --- head and tail ---------------------------------------------------------------------------
@clips.train("Look Around", "looks left, right and up; a paw lifts")
def look_around(b: ClipBuilder) -> None:
    """Standing, look left, right, up at something; ears swivel, one paw lifts (pointer)."""
    dog = Dog(b)
    first = b.sign()
    looks = [
        (0.0, 0.0, 0.0, 0.0),
        (10.0, first * 0.7, 0.0, 0.0),
        (22.0, first * 0.8, 0.1, 0.15),
        (34.0, -first * 0.7, 0.0, -0.1),
        (46.0, -first * 0.75, -0.2, 0.0),
        (58.0, 0.1 * first, -0.55, 0.0),
        (70.0, 0.0, -0.5, first * 0.4),
        (84.0, 0.0, 0.0, 0.0),
    ]
    for t, turn_, up, tilt in looks:
        turn_ = b.vary(turn_, 0.1)
        dog.neck(t, ry=0.6 * turn_, rx=up * 0.8 + 0.05, rz=-0.2 * turn_)
        dog.head(t, ry=0.4 * turn_, rx=up * 0.5, rz=tilt, follow=1.0 if t < 50 else 0.7)
        dog.eyes(t, tx=55.0 * math.sin(turn_), ty=-up * 40.0)
        dog.cog(t, tx=-2.0 * turn_, ry=0.08 * turn_, ty=-1.0, rx=0.12 * up)
        dog.spine(t, chest=(0.15 * up, 0.15 * turn_, 0.0), hips=(0.0, -0.05 * turn_, 0.0))
        alert = 1.0 if 50.0 <= t <= 72.0 else 0.3
        for side in SIDES:
            toward = 1.0 if (side == "l") == (turn_ > 0) else -1.0
            dog.ears(t, side, curl=0.4 * alert, rx=0.4 * alert, rz=0.15 * toward - 0.2 * alert)
        dog.tail(t, curl=0.25 + 0.3 * alert, lift=0.1 * alert, side_curl=-0.3 * turn_)
    # the pointer: one front paw lifts and folds while it stares up
    leg = "front_leg_l" if first > 0 else "front_leg_r"
    other = "front_leg_r" if first > 0 else "front_leg_l"
    dog.plant(leg, 0.0, 54.0, 0.0, 0.0, 0.0)
    dog.paw(54.0, leg, rx=0.0, rz=0.0)  # flat on the ground until it lifts and when it lands
    dog.paw(58.0, leg, ty=14.0, tz=2.0, rx=1.4, rz=0.2)
    dog.paw(70.0, leg, ty=15.0, tz=3.0, rx=1.5, rz=0.25)
    dog.plant(leg, 78.0, 84.0, 0.0, 0.0, b.vary(2.0, 1.0))
    dog.paw(78.0, leg, rx=0.0, rz=0.0)
    dog.leg(0.0, leg, roll=0.0, toe_tap=0.0)
    dog.leg(54.0, leg, roll=0.4)
    dog.leg(62.0, leg, roll=0.0, toe_tap=-0.3)
    dog.leg(78.0, leg, roll=0.0, toe_tap=0.0)
    dog.toes(58.0, leg, curl=0.8, spread=-0.2)
    dog.toes(78.0, leg, curl=0.1, spread=0.1)
    dog.plant(other, 0.0, 84.0, 0.0, 0.0, 0.0)
    dog.leg(58.0, other, bank=0.15 * first)
    for leg_ in HIND:
        dog.plant(leg_, 0.0, 84.0, 0.0, 0.0, 0.0)
    dog.carriage([0.0, 84.0])


@clips.train("Tail Wag", "a happy wag with hip wiggle and panting")
def tail_wag(b: ClipBuilder) -> None:
    """A happy wag: the tail's wave runs (phase keyed as a sawtooth), hips wiggle, panting."""
    dog = Dog(b)
    period = float(round(b.vary(8.0, 1.0)))
    wags = 7
    end = wags * period + 10.0
    amplitude = b.vary(0.45, 0.1)
    for k in range(wags):
        t = 4.0 + k * period
        dog.tail_wave(t, amplitude if k else 0.05, -math.pi, "linear")
        dog.tail_wave(t + period - 1.0, amplitude, math.pi - 2 * math.pi / period, "constant")
        swing = 1 if k % 2 == 0 else -1
        dog.spine(t, hips=(0.0, 0.12 * swing, 0.05 * swing), chest=(0.0, -0.04 * swing, 0.0))
        dog.cog(t, tx=1.5 * swing, ty=-1.0, rz=-0.02 * swing)
        dog.key(t, jaw_ctrl__rx=b.vary(0.3, 0.08))
        dog.head(t, ry=0.1 * swing, rz=-0.08 * swing, rx=-0.1)
    dog.tail_wave(end, 0.0, 0.0)
    for t, amount in ((0.0, 0.0), (8.0, 1.0), (end - 6.0, 1.0), (end, 0.2)):
        dog.tail(t, curl=0.9 * amount, lift=0.15 * amount, side_curl=0.0, tip=0.3 * amount)
        for side in SIDES:
            dog.ears(t, side, curl=-0.3 * amount, rx=-0.5 * amount, rz=0.4 * amount)
    dog.cog(end, tx=0.0, ty=0.0, rz=0.0)
    dog.spine(0.0)
    dog.spine(end)
    dog.head(0.0)
    dog.head(end)
    dog.key(0.0, jaw_ctrl__rx=0.0)
    dog.key(end, jaw_ctrl__rx=0.1)
    for leg in LEGS:
        dog.plant(leg, 0.0, end, 0.0, 0.0, 0.0)
    dog.carriage([0.0, end])


# --- legs off the ground ------------------------------------------------------------------------
# FK poses of a sitting hind leg (left-side convention, (rx, ry, rz) per joint, top down):
# matched to where the IK leg sits, and reaching up behind the ear (upper and lower end
# of a scratching stroke). Solved once against the rig, then keyed like an animator would.
HIND_SITTING_FK = [(-2.4, 0.58, -0.73), (2.7, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.96, 0.0, 0.0)]
HIND_SCRATCH_FK = (
    [(-0.96, 0.11, 0.18), (-1.81, 0.0, 0.0), (0.39, 0.0, 0.0), (0.5, 0.0, 0.0)],
    [(-0.69, 0.11, 0.14), (-2.04, 0.0, 0.0), (-0.04, 0.0, 0.0), (0.5, 0.0, 0.0)],
)


@clips.train("Scratch", "sits and scratches behind the ear with a hind leg in FK")
def scratch(b: ClipBuilder) -> None:
    """Sit and scratch behind one ear with a hind leg switched to FK, then the other."""
    dog = Dog(b)
    sat = 14.0
    order = ("hind_leg_l", "hind_leg_r") if b.sign() > 0 else ("hind_leg_r", "hind_leg_l")
    t = sat + 4.0
    for leg in order:
        side = _side(leg)
        other = HIND[1] if leg == HIND[0] else HIND[0]
        lean = -SIDES[side]
        switch, reach = t, t + 3.0
        strokes = round(b.vary(6.0, 1.0))
        release = reach + 2.0 * strokes
        back = release + 6.0
        dog.plant(leg, 0.0, switch, 0.0, 0.0, 0.0)
        dog.plant(leg, back, back + 4.0, 0.0, 0.0, 0.0)
        dog.leg(switch, leg, ik_fk=1.0)
        dog.leg(reach, leg, ik_fk=0.0)
        dog.leg(release + 3.0, leg, ik_fk=0.0)
        dog.leg(back, leg, ik_fk=1.0)
        dog.fk_leg(switch, leg, HIND_SITTING_FK)
        high, low = HIND_SCRATCH_FK
        for k in range(strokes + 1):
            pose = high if k % 2 == 0 else low
            dog.fk_leg(
                reach + 2.0 * k, leg, [(rx + b.vary(0.0, 0.03), ry, rz) for rx, ry, rz in pose]
            )
        dog.fk_leg(release + 3.0, leg, HIND_SITTING_FK)
        dog.toes(switch, leg, 0.1, 0.0)
        dog.toes(reach + 2.0, leg, 0.9, 0.4, each=[0.2, 0.1, 0.0, -0.1])
        dog.toes(back, leg, 0.2, 0.1)
        # the other hind paw grips; the body leans away and the head tilts into the paw
        dog.leg(switch, other, toe_tap=0.0)
        dog.leg(reach, other, toe_tap=b.vary(-0.3, 0.1))
        dog.leg(back, other, toe_tap=0.0)
        for t_, amount in ((switch, 0.0), (reach + 2.0, 1.0), (release, 1.0), (back, 0.0)):
            dog.cog(
                t_,
                ty=SIT["cog"]["ty"] + amount,
                tz=SIT["cog"]["tz"],
                rx=SIT["cog"]["rx"],
                rz=0.15 * lean * amount,
            )
            dog.neck(
                t_, rx=0.45 - 0.15 * amount, ry=-0.35 * lean * amount, rz=-0.45 * lean * amount
            )
            dog.head(t_, rx=0.4, ry=-0.2 * lean * amount, rz=0.5 * lean * amount, jaw=0.15 * amount)
            dog.ears(t_, side, curl=0.5 * amount, rz=0.6 * amount, rx=-0.3 * amount)
            dog.eyes(t_, tx=-30.0 * lean * amount, ty=-20.0 * amount)
        t = back + 4.0
    end = t + 4.0
    for t_, amount in ((0.0, 0.0), (sat, 1.0), (end, 1.0)):
        _sit_body(dog, t_, amount, b)
    for front in FRONT:
        dog.plant(front, 0.0, end, 0.0, 0.0, SIT["front_tz"] * 0.6)
    _sitting_tail(dog, 0.0, 0.0)
    _sitting_tail(dog, sat, 1.0)
    _sitting_tail(dog, end, 1.0, side_curl=0.4)
    dog.carriage([0.0, end])


@clips.train("Sniff", "nose to the ground following a scent")
def sniff(b: ClipBuilder) -> None:
    """Nose to the ground, following a scent a step forward, quick sniffs, head up."""
    dog = Dog(b)
    side = b.sign()
    dog.cog(0.0, ty=0.0, rx=0.0, tz=0.0)
    dog.cog(12.0, ty=-5.0, rx=0.2, tz=-2.0)
    dog.cog(36.0, ty=-6.0, rx=0.22, tz=6.0, tx=2.0 * side)
    dog.cog(60.0, ty=-6.0, rx=0.2, tz=8.0, tx=0.0)
    dog.cog(78.0, ty=-1.0, rx=0.0, tz=8.0, tx=0.0)
    for t, (down, sweep) in {
        0.0: (0.0, 0.0),
        12.0: (1.0, 0.0),
        24.0: (1.0, side),
        36.0: (1.1, 0.3 * side),
        48.0: (1.0, -0.6 * side),
        60.0: (0.9, 0.0),
        78.0: (0.0, 0.0),
    }.items():
        dog.neck(t, rx=0.8 * down, ry=0.35 * sweep)
        dog.spine(
            t,
            chest=(0.35 * down, 0.1 * sweep, 0.0),
            hips=(-0.1 * down, 0.0, 0.0),
            chest_t=(0.0, -3.0 * down, 2.0 * down),
        )
        dog.head(t, rx=0.45 * down, ry=0.25 * sweep, follow=1.0 - 0.4 * down)
        dog.eyes(t, ty=-50.0 * down, tx=20.0 * sweep)
        for s in SIDES:
            dog.ears(t, s, curl=0.3 * down, rx=0.6 * down, rz=0.2)
    # sniffs: quick small nose pumps
    for t in (16.0, 18.0, 20.0, 40.0, 42.0, 44.0):
        dog.key(t, jaw_ctrl__rx=0.02 if t % 4 else 0.06)
    dog.key(0.0, jaw_ctrl__rx=0.0)
    dog.key(78.0, jaw_ctrl__rx=0.0)
    for t in (0.0, 30.0, 60.0, 78.0):
        dog.tail(t, curl=0.2, lift=-0.1, sway=0.4, lag=0.5, phase=t / 10.0)
    # front paws follow the nose a step
    for i, leg in enumerate(FRONT if side > 0 else FRONT[::-1]):
        lift = 28.0 + 6.0 * i
        plants = [(0.0, lift, (0.0, 0.0)), (lift + 6.0, 78.0, (b.vary(1.0, 1.0), 10.0))]
        _stepping(
            dog, leg, plants, [(lift, lift + 6.0, lift + 2.0)], height=5.0, flex=0.6, peel=0.35
        )
    for i, leg in enumerate(HIND):
        lift = 46.0 + 6.0 * i
        plants = [(0.0, lift, (0.0, 0.0)), (lift + 6.0, 78.0, (0.0, 8.0))]
        _stepping(
            dog, leg, plants, [(lift, lift + 6.0, lift + 2.0)], height=4.0, flex=0.4, peel=0.3
        )
    for leg in FRONT:
        dog.leg(20.0, leg, toe_tap=0.0)
        dog.leg(24.0, leg, toe_tap=b.vary(0.3, 0.1))
        dog.leg(28.0, leg, toe_tap=0.0)
    dog.carriage([0.0, 78.0])


@clips.train("Shake Paw", "sitting, gives one paw then the other (FK)")
def shake_paw(b: ClipBuilder) -> None:
    """Sitting, give the right paw (FK), shake it, then the left one."""
    dog = Dog(b)
    end = 96.0
    for t, amount in ((0.0, 0.0), (14.0, 1.0), (end, 1.0)):
        _sit_body(dog, t, amount, b)
    for leg in HIND:
        dog.plant(leg, 0.0, end, 0.0, 0.0, 0.0)
    for i, leg in enumerate(("front_leg_r", "front_leg_l")):
        side = _side(leg)
        up = 20.0 + 40.0 * i
        down = up + 28.0
        dog.plant(leg, 0.0, up, 0.0, 0.0, SIT["front_tz"] * 0.7)
        dog.plant(leg, down + 6.0, end, 0.0, 0.0, SIT["front_tz"] * 0.7)
        dog.leg(up, leg, ik_fk=1.0)
        dog.leg(up + 4.0, leg, ik_fk=0.0)
        dog.leg(down, leg, ik_fk=0.0)
        dog.leg(down + 6.0, leg, ik_fk=1.0)
        sitting = [(0.75, 0.0, 0.0), (-0.05, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)]
        dog.fk_leg(up, leg, sitting)
        raised = b.vary(-0.9, 0.1)
        for k, t in enumerate((up + 6.0, up + 10.0, up + 14.0, up + 18.0, up + 22.0)):
            shake = 0.25 if k % 2 else -0.1
            dog.fk_leg(
                t,
                leg,
                [
                    (raised + shake, 0.05, 0.1),
                    (-0.2 - shake, 0.0, 0.0),
                    (0.6 + shake, 0.0, 0.05),
                    (0.3, 0.0, 0.0),
                ],
            )
        dog.fk_leg(down, leg, sitting)
        dog.toes(up + 6.0, leg, 0.6, 0.3, each=[0.1, 0.0, 0.0, 0.1])
        dog.toes(down, leg, 0.1, 0.0)
        for t, amount in ((up, 0.0), (up + 10.0, 1.0), (down, 0.0)):
            dog.key(
                t,
                **{
                    f"scapula_{side}_ctrl__rx": -0.25 * amount,
                    f"scapula_{side}_ctrl__ry": SIDES[side] * 0.1 * amount,
                    f"scapula_{side}_ctrl__rz": SIDES[side] * 0.15 * amount,
                },
            )
            dog.cog(
                t,
                rz=-SIDES[side] * 0.08 * amount,
                ty=SIT["cog"]["ty"],
                tz=SIT["cog"]["tz"],
                rx=SIT["cog"]["rx"],
            )
            dog.head(t, rx=0.4, rz=SIDES[side] * 0.3 * amount, ry=-SIDES[side] * 0.15 * amount)
    _sitting_tail(dog, 0.0, 0.0)
    _sitting_tail(dog, 20.0, 1.0)
    for t in (30.0, 38.0, 46.0, 70.0, 78.0):
        dog.tail_wave(t, 0.25, -math.pi if t in (30.0, 70.0) else 0.5)
    _sitting_tail(dog, end, 1.0, side_curl=-0.3)
    dog.carriage([0.0, 48.0, end], alert=0.6)


@clips.train("Play Bow", "two play bows, rump high, tail wagging")
def play_bow(b: ClipBuilder) -> None:
    """Drop the chest into a play bow twice, rump high, tail wagging, then stand."""
    dog = Dog(b)
    bows = ((10.0, 28.0), (40.0, 58.0))
    end = 76.0
    for leg in HIND:
        dog.plant(leg, 0.0, end, 0.0, 0.0, 0.0)
    for leg in FRONT:
        out = b.vary(16.0, 3.0)
        plants = [(0.0, 6.0, (0.0, 0.0)), (12.0, 64.0, (0.0, out)), (70.0, end, (0.0, 0.0))]
        swings = [(6.0, 12.0, 8.0), (64.0, 70.0, 66.0)]
        _stepping(dog, leg, plants, swings, height=6.0, flex=0.5, peel=0.3)
        for down, up in bows:
            dog.leg(down + 6.0, leg, roll=b.vary(-0.5, 0.1))
            dog.pole(down + 6.0, leg, ty=-8.0, tz=-10.0)
            dog.paw(down + 6.0, leg, rx=-0.2, rz=b.vary(0.15, 0.05))
            dog.leg(up, leg, roll=0.0)
            dog.pole(up, leg, ty=0.0, tz=0.0)
            dog.paw(up, leg, rx=0.0, rz=0.0)
    for t, bow in (
        (0.0, 0.0),
        (10.0, 0.2),
        (16.0, 1.0),
        (28.0, 1.0),
        (34.0, 0.1),
        (40.0, 0.3),
        (46.0, 1.0),
        (58.0, 0.9),
        (64.0, 0.2),
        (end, 0.0),
    ):
        dog.cog(t, ty=-14.0 * bow, rx=0.42 * bow, tz=-3.0 * bow)
        dog.spine(
            t, hips=(-0.3 * bow, 0.0, 0.0), chest=(0.1 * bow, 0.0, 0.0), mid=(0.0, -4.0 * bow, 0.0)
        )
        dog.neck(t, rx=-0.75 * bow)
        dog.head(t, rx=-0.2 * bow, rz=0.2 * bow * (1 if t > 35 else -1), jaw=0.25 * bow)
        for side in SIDES:
            dog.ears(t, side, curl=0.3 * bow, rx=0.4 * bow, rz=-0.1 * bow)
        dog.tail(t, curl=1.2 * bow, lift=0.3 * bow, tip=0.4 * bow)
    for k, t in enumerate(np.arange(16.0, 60.0, 6.0)):
        dog.tail_wave(float(t), 0.35, -math.pi + (k % 2) * math.pi)
    dog.tail_wave(0.0, 0.0, 0.0)
    dog.tail_wave(end, 0.0, 0.0)
    dog.carriage([0.0, 34.0, end], alert=0.8)


def _turn_paw(leg: str, angle: float, cog_z: float) -> tuple[float, float]:
    """Left-side (tx, tz) of a paw that keeps its place under a body yawed by ``angle``."""
    x, z = PAW_REST_XZ[leg[: leg.rindex("_")]]
    sign = SIDES[_side(leg)]
    x *= sign
    rel_z = z - COG_REST_Z
    nx = x * math.cos(angle) + rel_z * math.sin(angle)
    nz = -x * math.sin(angle) + rel_z * math.cos(angle) + COG_REST_Z + cog_z
    return sign * (nx - x), nz - z


@clips.train("Turn", "turns on the spot in two rounds of steps")
def turn(b: ClipBuilder) -> None:
    """Turn on the spot by 45-60 degrees in two rounds of steps, head leading."""
    dog = Dog(b)
    direction = b.sign()
    total = direction * b.vary(0.95, 0.1)
    order = ["front_leg_r", "front_leg_l", "hind_leg_r", "hind_leg_l"]
    if direction < 0:
        order = [_other_side(leg) for leg in order]
    # heading of the body at each round
    t_steps = {leg: [8.0 + 4.0 * i, 32.0 + 4.0 * i] for i, leg in enumerate(order)}
    end = 62.0
    dog.cog(0.0, ry=0.0, ty=0.0)
    dog.cog(6.0, ry=0.0, ty=-1.5, rz=-0.04 * direction)
    dog.cog(20.0, ry=0.5 * total, ty=-2.5, rz=-0.06 * direction)
    dog.cog(32.0, ry=0.6 * total, ty=-1.5, rz=-0.03 * direction)
    dog.cog(46.0, ry=total, ty=-2.0, rz=-0.05 * direction)
    dog.cog(end, ry=total, ty=0.0, rz=0.0)
    headings = [0.0, 0.55 * total, total]
    for leg in LEGS:
        plants, swings = [], []
        start = 0.0
        place = _turn_paw(leg, 0.0, 0.0)
        for i, lift in enumerate(t_steps[leg]):
            land = lift + 6.0
            plants.append((start, lift, place))
            swings.append((lift, land, lift + 2.0))
            start, place = land, _turn_paw(leg, headings[i + 1], 0.0)
        plants.append((start, end, place))
        _stepping(dog, leg, plants, swings, height=b.vary(5.0, 1.0), flex=0.6, peel=0.3)
        for (_, s_end, _), angle in zip(plants, headings, strict=True):
            dog.paw(s_end, leg, ry=angle)
            dog.leg(s_end, leg, bank=-0.08 * direction)
    for t, share in ((0.0, 0.0), (6.0, 0.5), (20.0, 1.0), (32.0, 0.6), (46.0, 1.0), (end, 0.0)):
        dog.neck(t, ry=direction * 0.5 * share, rx=0.05)
        dog.head(t, ry=direction * 0.35 * share, rz=-0.1 * direction * share)
        dog.eyes(t, tx=direction * 45.0 * share)
        dog.spine(
            t,
            hips=(0.0, -0.2 * direction * share, 0.0),
            chest=(0.0, 0.25 * direction * share, 0.04 * share),
        )
        dog.tail(
            t,
            curl=0.3,
            side_curl=-0.8 * direction * share,
            lift=0.1,
            sway=0.2,
            phase=share * math.pi,
        )
    dog.carriage([0.0, 32.0, end], alert=0.5)


# --- held-out test clips: large, fast, extreme --------------------------------------------------
@clips.test("Jumping & Playing", "leaps, spins and pounces")
def jumping_and_playing(b: ClipBuilder) -> None:
    """Crouch, leap forward, land, spin to chase the tail, pounce (fast and big)."""
    dog = Dog(b)
    # root carries the travel: two leaps forward and a half spin
    dog.root(0.0, tz=-80.0, ry=0.0)
    dog.root(10.0, tz=-80.0, ry=0.0)
    dog.root(22.0, tz=0.0, ry=0.0)
    dog.root(34.0, tz=10.0, ry=0.0)
    dog.root(46.0, tz=10.0, ry=b.vary(2.6, 0.3))
    dog.root(54.0, tz=14.0, tx=10.0, ry=b.vary(2.8, 0.3))
    dog.root(66.0, tz=70.0, tx=b.vary(40.0, 10.0), ry=b.vary(2.8, 0.3))
    # crouch, launch (stretch), airborne (tuck), land (compress), stand
    for t, (ty, rx, spine, tuck) in {
        0.0: (0.0, 0.0, 0.0, 0.0),
        8.0: (-18.0, 0.25, -1.0, 0.0),  # crouch, weight forward
        12.0: (10.0, -0.5, 1.0, 0.0),  # launch: stretched, nose up
        16.0: (26.0, 0.0, 0.5, 1.0),  # top: legs tucked
        20.0: (12.0, 0.45, -0.5, 0.5),  # descending, nose down
        23.0: (-14.0, 0.3, -1.0, 0.0),  # landing compression
        30.0: (-4.0, 0.0, 0.0, 0.0),
        40.0: (-10.0, 0.1, -0.6, 0.0),
        48.0: (-8.0, -0.1, 0.5, 0.0),
        56.0: (-20.0, 0.35, -1.0, 0.0),  # crouch for the pounce
        60.0: (22.0, -0.3, 1.0, 1.0),
        64.0: (8.0, 0.5, -0.4, 0.4),
        68.0: (-16.0, 0.5, -1.0, 0.0),  # pounce landing, front low
        76.0: (-6.0, 0.2, 0.0, 0.0),
    }.items():
        dog.cog(
            t,
            ty=ty,
            rx=rx,
            rz=0.2 * spine if 38 < t < 50 else 0.0,
            ry=0.3 * spine if 38 < t < 50 else 0.0,
        )
        dog.spine(
            t,
            hips=(0.35 * spine, 0.0, 0.0),
            chest=(-0.45 * spine, 0.0, 0.0),
            mid=(0.0, 7.0 * spine, 0.0),
            chest_t=(0.0, 3.0 * spine, 4.0 * spine),
        )
        for leg in FRONT:
            dog.paw(
                t, leg, ty=24.0 * tuck, tz=-14.0 * tuck + 6.0 * spine, rx=1.5 * tuck, tx=2.0 * tuck
            )
            dog.leg(t, leg, roll=0.6 * max(spine, 0.0), ik_fk=1.0)
        for leg in HIND:
            dog.paw(
                t,
                leg,
                ty=16.0 * tuck,
                tz=-22.0 * max(spine, 0.0) + 12.0 * tuck,
                rx=1.0 * max(spine, 0.0),
            )
            dog.leg(t, leg, roll=1.2 * max(spine, 0.0), hock=0.4 * tuck)
        dog.neck(t, rx=-0.6 * spine + 0.2, ry=0.4 if 40 < t < 56 else 0.0)
        dog.head(t, rx=0.3 * spine, jaw=0.5 * tuck + 0.1)
        dog.tail(t, curl=-0.8 * spine, lift=0.6 * spine, side_curl=2.0 if 40 < t < 54 else 0.0)
        for side in SIDES:
            dog.ears(t, side, curl=-1.0 * tuck, rx=-0.9 * tuck, rz=0.7 * tuck)
    dog.eyes(0.0, ty=-10.0)
    dog.eyes(46.0, tx=-50.0, ty=-30.0)
    dog.eyes(76.0, ty=-40.0)


@clips.test("Turning & Galloping", "gallops with sharp turns")
def turning_and_galloping(b: ClipBuilder) -> None:
    """Rotary gallop with two sharp turns: long strides, suspension, banking into the turns."""
    dog = Dog(b)
    period = 10.0
    cycles = 6
    end = period * cycles
    stride = b.vary(100.0, 8.0)
    turns = [(20.0, 30.0, b.vary(1.2, 0.2)), (44.0, 54.0, -b.vary(1.4, 0.2))]

    def heading(t):
        h = 0.0
        for start, stop, angle in turns:
            h += angle * min(max((t - start) / (stop - start), 0.0), 1.0)
        return h

    # the path, integrated on half-cycles and centred on the root's soft range
    times = np.arange(0.0, end + 1e-9, 5.0)
    path = [(0.0, 0.0)]
    for t in times[1:]:
        h = heading(t - 2.5)
        x, z = path[-1]
        path.append(
            (x + stride / period * 5.0 * math.sin(h), z + stride / period * 5.0 * math.cos(h))
        )
    path = np.array(path)
    path -= 0.5 * (path.min(axis=0) + path.max(axis=0))
    for t, (x, z) in zip(times, path, strict=True):
        dog.root(float(t), "linear", tx=x, tz=z, ry=heading(float(t)))
    # footfalls of a rotary gallop: LH, RH, RF, LF then suspension
    offsets = {"hind_leg_l": 0.0, "hind_leg_r": 1.0, "front_leg_r": 4.0, "front_leg_l": 5.0}
    reach = 0.2 * stride / 2.0 + 4.0
    for leg, offset in offsets.items():
        for k in range(cycles):
            land = k * period + offset
            lift = land + 3.0
            peak = land + 6.0
            b.key(f"{leg}_ik.tz", land, reach, "linear")
            b.key(f"{leg}_ik.tz", lift, reach - 0.3 * stride * 3.0 / period, "bezier")
            b.key(f"{leg}_ik.ty", land, 0.0, "linear")
            b.key(f"{leg}_ik.ty", lift, 0.0, "bezier")
            dog.paw(peak, leg, ty=b.vary(16.0, 3.0), tz=-reach * 0.8, rx=1.3)
            dog.leg(land, leg, roll=0.0)
            dog.leg(lift, leg, roll=0.8)
            dog.leg(peak, leg, roll=0.3)
            dog.paw(land, leg, rx=0.0)
    for k in range(cycles * 2 + 1):
        t = k * period / 2.0
        gather = k % 2 == 0
        bank = -0.35 * (heading(t + 3.0) - heading(t - 3.0))
        dog.cog(t, ty=(4.0 if not gather else -6.0), rx=-0.1 if gather else 0.1, rz=bank * 3.0)
        dog.spine(
            t,
            hips=(0.4 if gather else -0.3, 0.0, 0.0),
            chest=(-0.4 if gather else 0.3, 0.3 * bank, 0.0),
            mid=(0.0, 6.0 if gather else -4.0, 0.0),
        )
        dog.neck(t, rx=-0.3 if gather else 0.2, ry=2.0 * bank)
        dog.head(t, rx=0.2 if gather else -0.1)
        dog.tail(t, curl=-0.4, lift=0.1, side_curl=-3.0 * bank)
        for side in SIDES:
            dog.ears(t, side, curl=-0.8, rx=-1.0, rz=0.9)
    dog.eyes(0.0, ty=-20.0)
    dog.eyes(end, ty=-20.0)


@clips.test("Begging Excitedly", "sits up begging, paws paddling")
def begging_excitedly(b: ClipBuilder) -> None:
    """Sit up on the haunches, front paws paddling in FK, bouncing, tail going wild."""
    dog = Dog(b)
    up_at, end = 16.0, 84.0
    for t, amount in ((0.0, 0.0), (10.0, 1.0)):
        _sit_body(dog, t, amount, b)
    for leg in HIND:
        dog.plant(leg, 0.0, end, 0.0, 0.0, 0.0)
    for leg in FRONT:
        dog.plant(leg, 0.0, up_at - 4.0, 0.0, 0.0, SIT["front_tz"])
        dog.leg(up_at - 4.0, leg, ik_fk=1.0)
        dog.leg(up_at, leg, ik_fk=0.0)
        dog.leg(end, leg, ik_fk=0.0)
    pitch = b.vary(-1.45, 0.05)
    dog.tail(0.0, curl=0.3)
    dog.tail_wave(0.0, 0.0, 0.0)
    for k, t in enumerate(np.arange(up_at, end + 1e-9, 4.0)):
        bounce = 1.0 if k % 2 == 0 else 0.0
        dog.cog(
            float(t),
            ty=-24.0 + 5.0 * bounce,
            tz=-20.0,
            rx=pitch - 0.1 * bounce,
            rz=0.08 * math.sin(k),
        )
        dog.spine(
            float(t),
            hips=(0.6, 0.0, 0.0),
            chest=(-0.1 * bounce, 0.1 * math.sin(k), 0.0),
            mid=(0.0, 0.0, -4.0),
        )
        for i, leg in enumerate(FRONT):
            paddle = 1.0 if (k + i) % 2 == 0 else -1.0
            dog.fk_leg(
                float(t),
                leg,
                [
                    (-0.4 + 0.45 * paddle, 0.1, 0.25),
                    (1.3 - 0.4 * paddle, 0, 0),
                    (0.9, 0.0, 0.0),
                    (0.4, 0.0, 0.0),
                ],
            )
        dog.neck(float(t), rx=0.9 - 0.2 * bounce, ry=0.15 * math.sin(0.7 * k))
        dog.head(
            float(t), rx=0.9 + 0.15 * bounce, rz=0.2 * math.sin(0.5 * k), jaw=0.55 * bounce + 0.1
        )
        for side in SIDES:
            dog.ears(float(t), side, curl=-0.6 * bounce, rx=-0.5 + 0.8 * bounce, rz=0.8)
        dog.tail_wave(float(t), 0.6, -math.pi if k % 2 == 0 else 0.0)
        dog.tail(float(t), curl=-0.3, lift=0.55, side_curl=1.2 * (1 if k % 2 else -1))
    dog.eyes(0.0)
    dog.eyes(end, ty=40.0)


LIBRARY = clips.library("quadruped")
