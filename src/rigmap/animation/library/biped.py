"""The human's motion library: everyday training clips and three held-out test clips (§6.1).

Training: idle, walk, reach, crouch, wave, turn, pick up, kick, look around. Test
(the paper's Table 1 biped clips): "Range of Motion" (every limb to its extremes),
"Swing Dance" (fast footwork, spins, arm swings) and "Tai Chi" (slow, deep stance,
wide arm arcs, balance on one leg).

Conventions of the rig (centimetres, radians): the character faces +Z, +X is its
left, Y is up; its rest pose is a T-pose. Arms hang relaxed in FK (``arm_*.ik_fk``
= 0), since an IK hand keyed far from the T-pose would leave its soft range; arms go
to IK where a hand holds a place in space (reaching a shelf), switched on a pose
matched to the FK arm. IK feet are planted in root space; when the root travels
(the walk) a planted foot slides back at the root's speed on linear keys, so it stays
put in the world. Left-side values are given; right-side ``tx``, ``ry`` and ``rz`` of
limb controls change sign. Fingers follow the rig's own ``curl`` attribute, which
closes both hands towards the palm; the per-joint ``rz``/``ry`` detail is mirrored
(negated on the left hand) to bend the same way.
"""

from __future__ import annotations

import math

import numpy as np

from rigmap.animation.library import Clips
from rigmap.animation.library.body import SIDES, BodyKeys
from rigmap.animation.library.clip_builder import ClipBuilder

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
ARM_JOINTS = ("upper_arm", "forearm", "hand")
LEG_JOINTS = ("thigh", "shin", "foot", "ball")

# relaxed arms hanging by the sides, FK (rx, ry, rz) per joint, left-side convention
ARMS_DOWN = [(0.0, -0.1, -1.42), (0.0, -0.3, 0.0), (0.0, 0.0, -0.1)]
# an arm raised forward and out to chest height, and the IK hand and pole that match it
# (offsets from the T-pose, cm; rotations, rad) — solved once against the rig (least
# squares on elbow, wrist and finger tips; exact to 0.01 cm)
ARM_FORWARD = [(0.0, -0.4, -0.2), (0.0, -0.35, 0.0), (0.0, 0.0, 0.0)]
ARM_FORWARD_IK = {"tx": -10.37, "ty": -8.64, "tz": 27.57, "rx": 0.0, "ry": -0.75, "rz": -0.2}
ARM_FORWARD_POLE = {"tx": -4.7, "ty": -4.72, "tz": -19.58}
# hand shapes: per finger (curl, spread) of the rig's attributes
HAND_SHAPES = {
    "relaxed": {f: (0.45, 0.0) for f in FINGERS},
    "fist": {"thumb": (1.2, 0.4), **{f: (2.2, 0.0) for f in FINGERS[1:]}},
    "open": {
        "thumb": (-0.2, -0.3),
        "index": (-0.2, 0.3),
        "middle": (-0.2, 0.05),
        "ring": (-0.2, -0.15),
        "pinky": (-0.25, -0.3),
    },
    "point": {
        "thumb": (1.0, 0.3),
        "index": (0.0, 0.0),
        "middle": (2.1, 0.0),
        "ring": (2.2, 0.0),
        "pinky": (2.2, 0.0),
    },
    "grip": {"thumb": (0.8, 0.5), **{f: (1.4, 0.0) for f in FINGERS[1:]}},
}


class Human(BodyKeys):
    """Semantic keying on top of a :class:`ClipBuilder`: feet, arms, hands, spine, head."""

    # --- body ------------------------------------------------------------------------
    def head(self, frame: float, rx=0.0, ry=0.0, rz=0.0, jaw=None, follow=None, eyes=None) -> None:
        """Head turn spread over neck and head (totals, radians); ``eyes`` = aim offset (cm)."""
        for k, weight in enumerate((0.3, 0.25)):
            self.b.pose(
                frame,
                {
                    f"neck_{k + 1}_fk.rx": weight * rx,
                    f"neck_{k + 1}_fk.ry": weight * ry,
                    f"neck_{k + 1}_fk.rz": weight * rz,
                },
            )
        self.b.pose(frame, {"head.rx": 0.45 * rx, "head.ry": 0.45 * ry, "head.rz": 0.45 * rz})
        if jaw is not None:
            self.b.key("jaw_ctrl.rx", frame, jaw)
        if follow is not None:
            self.b.key("head.follow", frame, follow)
        if eyes is not None:
            self.b.pose(
                frame, {f"eye_aim.{c}": v for c, v in zip(("tx", "ty", "tz"), eyes, strict=True)}
            )

    # --- legs ---------------------------------------------------------------------------
    def foot(self, frame: float, side: str, interpolation: str = "bezier", **channels) -> None:
        self._mirrored(f"leg_{side}_ik", side, channels, frame, interpolation)

    def plant(self, side: str, start: float, end: float, tx: float, ty: float, tz: float) -> None:
        self._hold(f"leg_{side}_ik", side, start, end, tx, ty, tz)

    def leg(self, frame: float, side: str, **attributes) -> None:
        """``roll``, ``bank``, ``heel_twist``, ``toe_twist``, ``toe_tap``, ``ik_fk``."""
        for name, value in attributes.items():
            if name in ("heel_twist", "toe_twist"):
                value = SIDES[side] * value
            self.b.key(f"leg_{side}.{name}", frame, value)

    def knee(self, frame: float, side: str, **channels) -> None:
        self._mirrored(f"leg_{side}_pole", side, channels, frame)

    def fk_leg(self, frame: float, side: str, angles, looseness: float = 0.03) -> None:
        self._fk_joints(frame, LEG_JOINTS, side, angles, looseness)

    # --- arms and hands -------------------------------------------------------------------
    def arm(
        self, frame: float, side: str, angles, clavicle=(0.0, 0.0), looseness: float = 0.03
    ) -> None:
        """FK arm: (rx, ry, rz) for upper arm, forearm, hand; clavicle (ry, rz)."""
        self._fk_joints(frame, ARM_JOINTS, side, angles, looseness, loose=("rx", "rz"))
        self._mirrored(f"clavicle_{side}_ctrl", side, {"ry": clavicle[0], "rz": clavicle[1]}, frame)

    def drawn_sides(self) -> tuple[str, str]:
        """``(side, other)``: the side this take favours, drawn by ``ClipBuilder.sign`` (so a
        held-out take can keep its training take's), and the other side."""
        side = "r" if self.b.sign() > 0 else "l"
        return side, "l" if side == "r" else "r"

    def walk_steps(
        self,
        side: str,
        phase: float,
        period: float,
        grid: float,
        cycles: int,
        end: float,
        *,
        reach: float,
        height: float,
        strike_roll,
        toe_off_roll,
        scale=None,
    ) -> None:
        """A walk's leg keys on one side: strike, mid-stance, toe-off and passing pose of
        every cycle that falls in ``[0, end]``. ``strike_roll()``/``toe_off_roll()`` give
        the foot roll at each strike/toe-off (called when keyed, so a drawn roll keeps its
        place in the clip's random stream); ``scale(t)`` (default 1) shrinks reach, rolls
        and foot lift (a walk starting or stopping)."""
        b = self.b

        def w(t: float) -> float:
            return 1.0 if scale is None else scale(t)

        for k in range(-1, cycles + 1):
            strike = phase + k * period
            toe_off, mid = strike + 18.0, strike + 9.0
            passing = toe_off + 6.0
            if 0.0 <= strike <= end:
                b.key(f"leg_{side}_ik.tz", strike, reach * w(strike), "linear")
                b.key(f"leg_{side}_ik.ty", strike, 0.0, "linear")
                self.leg(strike, side, roll=strike_roll() * w(strike))
                self.foot(strike, side, rx=0.0)
            if 0.0 <= strike + grid <= end:
                self.leg(strike + grid, side, roll=0.0)
            if 0.0 <= mid <= end:
                b.key(f"leg_{side}_ik.tz", mid, 0.0, "linear")
                b.key(f"leg_{side}_ik.ty", mid, 0.0, "linear")
            if 0.0 <= toe_off - grid <= end:
                self.leg(toe_off - grid, side, roll=0.2 * w(toe_off - grid))
            if 0.0 <= toe_off <= end:
                b.key(f"leg_{side}_ik.tz", toe_off, -reach * w(toe_off), "bezier")
                b.key(f"leg_{side}_ik.ty", toe_off, 0.0, "bezier")
                self.leg(toe_off, side, roll=toe_off_roll() * w(toe_off))
                self.foot(toe_off, side, rx=0.0)
            if 0.0 <= passing <= end:
                lift = w(passing)
                self.foot(passing, side, ty=height * lift, tz=0.0, rx=-0.25 * lift)
                self.leg(passing, side, roll=0.0)

    def walk_arm_swing(
        self,
        side: str,
        phase: float,
        period: float,
        cycles: int,
        end: float,
        swing: float,
        scale=None,
    ) -> None:
        """A walk's arm swing: this side's arm forward while the other leg strikes, back half
        a cycle later; ``scale(t)`` (default 1) shrinks each swing (a walk starting or
        stopping)."""
        for k in range(cycles + 1):
            forward = phase + period / 2 + k * period - period
            for t, amount in ((forward, 1.0), (forward + period / 2, -1.0)):
                if 0.0 <= t <= end:
                    a = amount if scale is None else amount * scale(t)
                    self.arm(
                        t,
                        side,
                        [
                            (0.0, -swing * a - 0.05, -1.42),
                            (0.0, -0.35 - 0.15 * max(a, 0.0), 0.0),
                            (0.0, 0.0, -0.1),
                        ],
                    )

    def relaxed_hands(self, end: float) -> None:
        """Both arms in FK with relaxed hands at the first and last frame."""
        for side in SIDES:
            self.ik_fk(0.0, side, 0.0)
            self.ik_fk(end, side, 0.0)
            self.hand(0.0, side, "relaxed")
            self.hand(end, side, "relaxed", amount=0.8)

    def hand_ik(self, frame: float, side: str, **channels) -> None:
        self._mirrored(f"arm_{side}_ik", side, channels, frame)

    def elbow(self, frame: float, side: str, **channels) -> None:
        self._mirrored(f"arm_{side}_pole", side, channels, frame)

    def ik_fk(self, frame: float, side: str, value: float, limb: str = "arm") -> None:
        self.b.key(f"{limb}_{side}.ik_fk", frame, value)

    def hand(
        self,
        frame: float,
        side: str,
        shape: str = "relaxed",
        amount: float = 1.0,
        wobble: float = 0.08,
    ) -> None:
        """A hand shape: the rig's curl/spread attributes plus per-joint detail."""
        for finger, (curl, spread) in HAND_SHAPES[shape].items():
            relaxed_curl, _ = HAND_SHAPES["relaxed"][finger]
            curl = relaxed_curl + amount * (curl - relaxed_curl)
            self.b.key(f"{finger}_{side}.curl", frame, self.b.vary(curl, wobble))
            self.b.key(f"{finger}_{side}.side_curl", frame, self.b.vary(amount * spread, wobble))
            # the last joints follow the curl a little more, the base spreads a little
            # per-joint channels are world-aligned, so the left hand's are mirrored
            mirror = -SIDES[side]
            for k, share in enumerate((0.0, 0.06, 0.1)):
                self.b.key(
                    f"{finger}_{k + 1}_{side}_fk.rz",
                    frame,
                    self.b.vary(mirror * share * curl, wobble * 0.5),
                )
                self.b.key(
                    f"{finger}_{k + 1}_{side}_fk.ry",
                    frame,
                    self.b.vary(mirror * 0.1 * spread if k == 0 else 0.0, wobble * 0.5),
                )

    # --- whole-body helpers -------------------------------------------------------------------
    def stand(self, frame: float, arms=True, hands: str | None = "relaxed") -> None:
        """Both arms relaxed in FK (and the FK switch held)."""
        for side in SIDES:
            if arms:
                self.ik_fk(frame, side, 0.0)
                self.arm(frame, side, ARMS_DOWN)
            if hands:
                self.hand(frame, side, hands)

    def planted_feet(self, start: float, end: float) -> None:
        for side in SIDES:
            self.plant(side, start, end, 0.0, 0.0, 0.0)

    def polish(self, frames) -> None:
        """Secondary controls per shot (poles, eye line, toes), seeded; animated ones kept."""
        b = self.b

        def key_frame(person: Human, frame: float) -> None:
            for side in SIDES:
                person.knee(
                    frame, side, tx=b.vary(2.0, 3.0), ty=b.vary(0.0, 3.0), tz=b.vary(0.0, 4.0)
                )
                person.elbow(
                    frame, side, tx=b.vary(0.0, 3.0), ty=b.vary(0.0, 3.0), tz=b.vary(-2.0, 4.0)
                )
                person.leg(frame, side, toe_tap=b.vary(0.0, 0.05), bank=b.vary(0.0, 0.04))
            person.b.pose(
                frame,
                {
                    "eye_aim.tx": b.vary(0.0, 12.0),
                    "eye_aim.ty": b.vary(0.0, 6.0),
                    "eye_aim.tz": b.vary(0.0, 10.0),
                },
            )

        self._polish(frames, key_frame)


# this library's clip functions, in corpus order (see rigmap.animation.library.Clips)
clips = Clips()


# --- training clips ----------------------------------------------------------------------------


@clips.train("Idle", "breathing, weight shifts, a glance, a foot readjusts")
def idle(b: ClipBuilder) -> None:
    """Standing: breathing, weight shifts from foot to foot, a glance, fidgeting fingers."""
    h = Human(b)
    end = 96.0
    first = b.sign()
    h.stand(0.0)
    h.stand(end)
    for k, t in enumerate(np.arange(0.0, end + 1e-9, 12.0)):
        t = float(t)
        side = first * (1 if (k // 2) % 2 == 0 else -1)
        breath = 1.0 if k % 2 else 0.0
        h.cog(t, tx=3.0 * side, ty=-1.0 - 0.5 * breath, rz=-0.02 * side)
        h.spine(
            t,
            hips=(0.0, 0.02 * side, 0.06 * side),
            chest=(-0.03 * breath, 0.0, -0.03 * side),
            chest_t=(0.0, 0.6 * breath, 0.3 * breath),
        )
        if 0 < t < end:
            for s in SIDES:
                h.arm(
                    t,
                    s,
                    [
                        (0.0, -0.1 + 0.05 * side * SIDES[s], -1.4 + 0.03 * breath),
                        (0.0, -0.3 - 0.1 * breath, 0.0),
                        (0.05, 0.0, -0.1),
                    ],
                )
    for t, (ry, rx) in {
        0.0: (0.0, 0.0),
        30.0: (first * 0.6, 0.05),
        42.0: (first * 0.55, -0.05),
        60.0: (-first * 0.2, 0.1),
        end: (0.0, 0.0),
    }.items():
        h.head(t, ry=ry, rx=rx, eyes=(50.0 * ry, -20.0 * rx, 0.0))
    for t in (20.0, 50.0, 76.0):
        for s in SIDES:
            h.hand(t, s, "relaxed", amount=b.vary(1.0, 0.4))
    # one foot readjusts under the shifted weight
    side = "l" if first > 0 else "r"
    other = "r" if side == "l" else "l"
    h.plant(side, 0.0, 64.0, 0.0, 0.0, 0.0)
    h.foot(68.0, side, tx=2.0, ty=5.0, tz=3.0, ry=0.1)
    h.plant(side, 72.0, end, b.vary(3.0, 1.5), 0.0, b.vary(4.0, 2.0))
    h.foot(72.0, side, ry=0.15)
    h.foot(64.0, side, ry=0.0)
    h.leg(60.0, side, roll=0.0)
    h.leg(64.0, side, roll=0.5)
    h.leg(72.0, side, roll=0.0)
    h.plant(other, 0.0, end, 0.0, 0.0, 0.0)
    h.polish([0.0, end])


@clips.train("Walk", "three cycles of a casual walk, root travelling")
def walk(b: ClipBuilder) -> None:
    """Three cycles of a casual walk; the root travels, planted feet slide back with it.

    Heel strike with the toes up (``roll`` < 0), foot flat, heel off and toe off
    (``roll`` > 0), swing with the toes clearing; arms swing against the legs.
    """
    h = Human(b)
    period, grid, cycles = 30.0, 3.0, 3
    step = b.vary(44.0, 3.0)
    reach = 0.3 * step  # a stance (0.6 of a cycle) sweeps 0.6 of a stride = 1.2 steps
    end = cycles * period
    speed = 2 * step / period
    heading = b.vary(0.0, 0.3)
    start_z = -0.5 * speed * end
    for t in np.arange(0.0, end + 1e-9, grid):
        d = start_z + speed * t
        interpolation = "linear" if 0 < t < end else "bezier"
        h.root(
            float(t), interpolation, tx=d * math.sin(heading), tz=d * math.cos(heading), ry=heading
        )
    strikes = {"l": 0.0, "r": period / 2}
    height = b.vary(12.0, 2.0)
    swing_arm = b.vary(0.25, 0.06)
    for side, phase in strikes.items():
        h.walk_steps(
            side,
            phase,
            period,
            grid,
            cycles,
            end,
            reach=reach,
            height=height,
            strike_roll=lambda: b.vary(-0.3, 0.05),
            toe_off_roll=lambda: b.vary(0.9, 0.1),
        )
        h.walk_arm_swing(side, phase, period, cycles, end, swing_arm)
    h.relaxed_hands(end)
    # body: lowest at double support, sways over the stance foot, hips rotate with legs
    for k, t in enumerate(np.arange(0.0, end + 1e-9, 7.5)):
        t = float(t)
        phase = k % 4  # 0: left strike, 2: right strike
        stance = 1.0 if phase in (0, 1) else -1.0
        h.cog(t, ty=-3.0 - (1.5 if phase % 2 == 0 else 0.0), tx=1.5 * stance, tz=0.0, ry=0.0)
        h.spine(
            t,
            hips=(0.02, 0.12 * (1 if phase == 0 else -1 if phase == 2 else 0), -0.05 * stance),
            chest=(0.05, -0.1 * (1 if phase == 0 else -1 if phase == 2 else 0), 0.02 * stance),
        )
        h.head(t, rx=0.05, ry=b.vary(0.0, 0.1))


@clips.train("Reach", "steps in and reaches a shelf (FK to IK on a matched pose)")
def reach(b: ClipBuilder) -> None:
    """Reach for a box on a shelf: one arm rises in FK, switches to IK on a matched pose,
    grabs; the other arm joins the same way and both hands bring it in, then back to FK."""
    h = Human(b)
    first, second = h.drawn_sides()
    end = 96.0
    h.stand(0.0)
    h.stand(end)
    # a step towards the shelf with the first arm's foot, and back
    h.plant(second, 0.0, end, 0.0, 0.0, 0.0)
    h.plant(first, 0.0, 16.0, 0.0, 0.0, 0.0)
    h.foot(20.0, first, ty=6.0, tz=8.0)
    h.plant(first, 24.0, 72.0, 2.0, 0.0, b.vary(16.0, 3.0))
    h.foot(76.0, first, ty=5.0, tz=8.0)
    h.plant(first, 80.0, end, 0.0, 0.0, 0.0)
    for t, roll in ((12.0, 0.0), (16.0, 0.6), (24.0, 0.0), (68.0, 0.0), (72.0, 0.6), (80.0, 0.0)):
        h.leg(t, first, roll=roll)
    box = {"tx": b.vary(-4.0, 4.0), "ty": b.vary(8.0, 4.0), "tz": b.vary(27.0, 2.0)}
    held = {"tx": -20.0, "ty": -16.0, "tz": 16.0}
    for side, rise, switch, grab in ((first, 8.0, 20.0, 30.0), (second, 30.0, 40.0, 48.0)):
        back, down = 62.0, 70.0
        h.arm(rise, side, [(0.0, -0.3, -1.0), (0.0, -0.7, 0.0), (0.0, 0.0, -0.1)])
        h.arm(switch, side, ARM_FORWARD, looseness=0.0)
        h.arm(back + 3.0, side, ARM_FORWARD, looseness=0.0)
        h.arm(down + 8.0, side, [(0.0, -0.4, -1.1), (0.0, -0.8, 0.0), (0.0, 0.0, -0.1)])
        h.ik_fk(switch, side, 0.0)
        h.ik_fk(switch + 3.0, side, 1.0)
        h.ik_fk(back, side, 1.0)
        h.ik_fk(back + 3.0, side, 0.0)
        reach_to = box if side == first else {**box, "tx": box["tx"] - 8.0, "ty": box["ty"] - 4.0}
        keys = {
            switch: ARM_FORWARD_IK,
            grab: {**ARM_FORWARD_IK, **reach_to, "rz": -0.1},
            54.0: {**ARM_FORWARD_IK, **held, "rz": -0.3, "rx": 0.3},
            back: ARM_FORWARD_IK,
        }
        if side == first:
            keys[40.0] = {**ARM_FORWARD_IK, **box, "rz": -0.1, "rx": 0.1}
        for t, values in keys.items():
            h.hand_ik(t, side, **values)
            pole = dict(ARM_FORWARD_POLE)
            if t not in (switch, back):
                pole["ty"] -= 8.0
            h.elbow(t, side, **pole)
        h.hand(switch, side, "open")
        h.hand(grab, side, "grip")
        h.hand(back, side, "grip")
        h.hand(down + 8.0, side, "relaxed")
    # body: lean in, look at the shelf
    for t, lean in (
        (0.0, 0.0),
        (16.0, 0.3),
        (30.0, 1.0),
        (48.0, 0.8),
        (54.0, 0.4),
        (62.0, 0.3),
        (end, 0.0),
    ):
        toward = SIDES[first]
        h.cog(t, tz=8.0 * lean, ty=-3.0 * lean, tx=-3.0 * toward * lean, rx=0.08 * lean)
        h.spine(
            t, chest=(0.1 * lean, -0.2 * toward * lean, 0.05 * lean), chest_t=(0.0, 0.0, 2.0 * lean)
        )
        h.head(
            t,
            rx=-0.15 * lean,
            ry=-0.3 * toward * lean,
            eyes=(-25.0 * toward * lean, 10.0 * lean, 0.0),
        )
    h.polish([0.0, end])


@clips.train("Crouch", "squats low with arms forward, stands")
def crouch(b: ClipBuilder) -> None:
    """Squat down low, balance with the arms forward, look at the floor, stand up."""
    h = Human(b)
    down, low, up, end = 16.0, 46.0, 62.0, 78.0
    depth = b.vary(-28.0, 1.5)
    look = b.sign()
    h.planted_feet(0.0, end)
    h.stand(0.0)
    h.stand(end)
    for t, amount in (
        (0.0, 0.0),
        (8.0, 0.1),
        (down, 0.9),
        (24.0, 1.0),
        (32.0, 1.0),
        (40.0, 0.95),
        (low, 1.0),
        (54.0, 0.6),
        (up, 0.3),
        (end, 0.0),
    ):
        sway = math.sin(t / 8.0) * (0 < t < end)
        h.cog(t, ty=depth * amount, tz=-8.0 * amount, rx=0.35 * amount, tx=2.0 * sway * amount)
        h.spine(
            t,
            hips=(0.25 * amount, 0.0, 0.03 * sway),
            chest=(0.2 * amount, 0.0, 0.0),
            mid=(0.5 * sway, -2.0 * amount, -3.0 * amount),
            chest_t=(1.0 * sway, -1.0 * amount, 1.0 * amount),
        )
        for side in SIDES:
            h.knee(t, side, tz=12.0 * amount, tx=5.0 * amount)
            h.leg(t, side, roll=0.3 * amount, bank=0.05 * amount)
            h.foot(t, side, ry=0.15 * amount, rz=0.04 * amount)
        scan = look * (0.4 if t == 32.0 else -0.3 if t == 40.0 else 0.0)
        h.head(
            t,
            rx=0.2 * amount + (0.4 * amount if t in (24.0, 32.0) else 0.0),
            ry=scan,
            eyes=(40.0 * scan, -30.0 * amount, 0.0),
        )
    for side in SIDES:
        for t, amount in ((8.0, 0.2), (down, 1.0), (low, 0.9), (up, 0.3)):
            h.arm(
                t,
                side,
                [
                    (0.1, -1.2 * amount - 0.1, -1.4 + 0.6 * amount),
                    (0.0, -0.3 - 0.6 * amount, 0.0),
                    (0.0, 0.2 * amount, -0.1),
                ],
                clavicle=(-0.1 * amount, 0.05 * amount),
            )
        h.hand(down, side, "open", amount=0.5)
        h.hand(low, side, "relaxed")
    h.polish([0.0, 30.0, end])


@clips.train("Wave", "raises a hand and waves")
def wave(b: ClipBuilder) -> None:
    """Raise a hand and wave hello (forearm swinging, fingers spread), then lower it."""
    h = Human(b)
    side, other = h.drawn_sides()
    waves = round(b.vary(4.0, 1.0))
    up = 14.0
    end = up + 6.0 * waves + 22.0
    h.planted_feet(0.0, end)
    h.stand(0.0)
    h.stand(end)
    h.arm(4.0, side, [(0.0, -0.15, -1.3), (0.0, -0.5, 0.0), (0.0, 0.0, -0.1)])
    h.arm(8.0, side, [(0.0, -0.3, -0.6), (0.0, -0.8, 0.2), (0.0, 0.0, 0.0)])
    for k in range(waves + 1):
        t = up + 6.0 * k
        swing = 1.0 if k % 2 == 0 else -1.0
        h.arm(
            t,
            side,
            [
                (b.vary(-1.4, 0.1), -0.2, 0.7),
                (0.0, 0.1, 1.3 + 0.3 * swing),
                (0.0, 0.0, 0.15 * swing),
            ],
            clavicle=(0.0, 0.15),
        )
        h.hand(t, side, "open", amount=b.vary(1.0, 0.2))
    lowered = up + 6.0 * waves + 8.0
    h.arm(lowered, side, [(0.0, -0.3, -0.8), (0.0, -0.7, 0.0), (0.0, 0.0, -0.1)])
    h.hand(lowered, side, "relaxed")
    h.arm(lowered + 6.0, side, [(0.0, -0.15, -1.3), (0.0, -0.45, 0.0), (0.0, 0.0, -0.1)])
    h.hand(lowered + 6.0, side, "relaxed", amount=0.8)
    h.arm(up, other, [(0.0, -0.05, -1.38), (0.0, -0.4, 0.0), (0.0, 0.0, -0.1)])
    for t, amount in ((0.0, 0.0), (up, 1.0), (lowered, 0.5), (end, 0.0)):
        h.head(
            t,
            rz=0.12 * SIDES[side] * amount,
            ry=-0.1 * SIDES[side] * amount,
            rx=-0.05 * amount,
            jaw=0.05 * amount,
            eyes=(0.0, 10.0 * amount, 0.0),
        )
        h.cog(t, tx=-2.0 * SIDES[side] * amount, ty=-0.5 * amount)
        h.spine(t, chest=(-0.03 * amount, 0.0, -0.06 * SIDES[side] * amount))
    h.polish([0.0, end])


def _turned_foot(side: str, angle: float) -> tuple[float, float]:
    """Left-side (tx, tz) keeping a foot under a body yawed by ``angle`` about the COG."""
    x, z = 9.0 * SIDES[side], -1.0
    nx = x * math.cos(angle) + z * math.sin(angle)
    nz = -x * math.sin(angle) + z * math.cos(angle)
    return SIDES[side] * (nx - x), nz - z


@clips.train("Turn", "turns on the spot about 90 degrees in three steps")
def turn(b: ClipBuilder) -> None:
    """Turn on the spot by about 90 degrees in three steps, head and chest leading."""
    h = Human(b)
    direction = b.sign()
    total = direction * b.vary(1.5, 0.15)
    lead = "l" if direction > 0 else "r"
    trail = "r" if lead == "l" else "l"
    steps = [(lead, 10.0, 0.5), (trail, 22.0, 1.0), (lead, 36.0, 1.0)]
    end = 56.0
    h.stand(0.0)
    h.stand(end)
    placed = {lead: (0.0, 0.0, 0.0), trail: (0.0, 0.0, 0.0)}
    since = {lead: 0.0, trail: 0.0}
    for side, lift, share in steps:
        land = lift + 8.0
        tx, tz, angle = placed[side]
        h.plant(side, since[side], lift, tx, 0.0, tz)
        h.foot(since[side], side, ry=angle)
        h.foot(lift, side, ry=angle)
        h.leg(lift - 3.0, side, roll=0.0, heel_twist=0.0)
        h.leg(lift, side, roll=0.5, heel_twist=0.0)
        h.leg(land, side, roll=0.0, heel_twist=0.0)
        # the planted foot pivots on its heel while the other one swings
        other = trail if side == lead else lead
        h.leg(lift + 4.0, other, heel_twist=0.25 * direction * SIDES[other])
        h.leg(land + 2.0, other, heel_twist=0.0)
        new_angle = share * total
        ntx, ntz = _turned_foot(side, new_angle)
        h.foot(
            lift + 4.0,
            side,
            tx=0.5 * (tx + ntx),
            ty=8.0,
            tz=0.5 * (tz + ntz),
            ry=0.5 * (angle + new_angle),
        )
        placed[side] = (ntx, ntz, new_angle)
        since[side] = land
    for side in SIDES:
        tx, tz, angle = placed[side]
        h.plant(side, since[side], end, tx, 0.0, tz)
        h.foot(since[side], side, ry=angle)
        h.foot(end, side, ry=angle)
    for t, share in ((0.0, 0.0), (6.0, 0.15), (14.0, 0.45), (26.0, 0.8), (40.0, 1.0), (end, 1.0)):
        h.cog(t, ry=share * total, ty=-1.5 * (0 < share < 1), tx=0.0)
        lead_share = min(1.0, share + 0.3) - share if t < end else 0.0
        h.spine(
            t,
            chest=(0.0, 1.2 * lead_share * total, 0.0),
            hips=(0.0, -0.3 * lead_share * total, 0.0),
        )
        h.head(t, ry=1.5 * lead_share * total, eyes=(40.0 * lead_share * direction, 0.0, 0.0))
    for side in SIDES:
        h.arm(
            20.0,
            side,
            [
                (0.0, -0.1 + 0.15 * SIDES[side] * direction, -1.35),
                (0.0, -0.4, 0.0),
                (0.0, 0.0, -0.1),
            ],
        )
    h.polish([0.0, end])


@clips.train("Pick Up", "bends down and lifts an object to the chest")
def pick_up(b: ClipBuilder) -> None:
    """Bend down, pick an object off the floor with both hands, lift it to the chest."""
    h = Human(b)
    bend, grab, lift, hold, end = 18.0, 30.0, 46.0, 58.0, 76.0
    h.planted_feet(0.0, end)
    h.stand(0.0)
    for t, (down, pitch) in {
        0.0: (0.0, 0.0),
        10.0: (0.2, 0.3),
        bend: (0.8, 0.9),
        24.0: (0.95, 1.0),
        grab: (1.0, 1.0),
        38.0: (0.8, 0.8),
        lift: (0.2, 0.2),
        52.0: (0.1, 0.05),
        hold: (0.05, 0.0),
        66.0: (0.02, 0.0),
        end: (0.0, 0.0),
    }.items():
        h.cog(
            t,
            ty=b.vary(-30.0, 3.0) * down if 0 < down < 1 else -30.0 * down,
            tz=-12.0 * down,
            rx=0.55 * pitch,
        )
        h.spine(
            t,
            hips=(0.3 * pitch, 0.0, 0.0),
            chest=(0.35 * pitch, 0.0, 0.0),
            mid=(0.0, 0.0, -4.0 * pitch),
        )
        h.head(t, rx=0.3 * pitch - 0.2 * down, eyes=(0.0, -40.0 * pitch, 0.0))
        for side in SIDES:
            h.knee(t, side, tz=14.0 * down, tx=4.0 * down)
            h.leg(t, side, roll=0.15 * down)
    for side in SIDES:
        h.arm(bend, side, [(0.3, -0.9, -1.25), (0.0, -0.2, 0.0), (0.0, 0.3, -0.2)])
        h.arm(grab, side, [(0.35, -1.1, -1.3), (0.0, -0.15, 0.2), (0.4, 0.3, -0.3)])
        h.arm(lift, side, [(0.3, -0.6, -1.3), (0.0, -1.4, 0.3), (0.4, 0.2, -0.3)])
        h.arm(hold, side, [(0.2, -0.4, -1.3), (0.0, -1.9, 0.3), (0.4, 0.2, -0.3)])
        h.arm(end, side, [(0.2, -0.35, -1.3), (0.0, -1.85, 0.3), (0.4, 0.2, -0.3)])
        h.hand(bend, side, "open")
        h.hand(grab, side, "grip")
        h.hand(52.0, side, "grip", amount=1.1)
        h.hand(66.0, side, "grip", amount=0.95)
        h.hand(end, side, "grip", amount=0.9)
        h.ik_fk(end, side, 0.0)
    h.polish([0.0, end])


@clips.train("Kick", "kicks a ball with one leg in FK, then the other")
def kick(b: ClipBuilder) -> None:
    """Kick a ball with one leg (switched to FK), recover, then a smaller kick with the other."""
    h = Human(b)
    order = h.drawn_sides()
    t = 8.0
    h.stand(0.0)
    for n, side in enumerate(order):
        support = order[1 - n]
        power = 1.0 if n == 0 else 0.6
        switch, wind, strike, follow, down = t, t + 8.0, t + 12.0, t + 18.0, t + 28.0
        h.plant(side, 0.0 if n == 0 else t - 8.0, switch, 0.0, 0.0, 0.0)
        h.plant(side, down + 4.0, down + 12.0, 0.0, 0.0, 0.0)
        h.ik_fk(switch, side, 1.0, limb="leg")
        h.ik_fk(switch + 3.0, side, 0.0, limb="leg")
        h.ik_fk(down, side, 0.0, limb="leg")
        h.ik_fk(down + 4.0, side, 1.0, limb="leg")
        h.fk_leg(switch, side, [(0.0, 0.0, 0.0)] * 4)
        h.fk_leg(
            wind,
            side,
            [(0.5 * power, 0.0, 0.05), (1.3 * power, 0.0, 0.0), (0.5, 0.0, 0.0), (0.0, 0.0, 0.0)],
        )
        h.fk_leg(
            strike,
            side,
            [(-0.9 * power, 0.1, 0.05), (0.25, 0.0, 0.0), (0.6, 0.0, 0.0), (0.2, 0.0, 0.0)],
        )
        h.fk_leg(
            follow,
            side,
            [(-1.2 * power, 0.1, 0.1), (0.4, 0.0, 0.0), (0.5, 0.0, 0.0), (0.1, 0.0, 0.0)],
        )
        h.fk_leg(down, side, [(0.0, 0.0, 0.0), (0.05, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)])
        for tt, amount in (
            (switch, 0.0),
            (wind, 1.0),
            (strike, 0.6),
            (follow, 1.0),
            (down, 0.3),
            (down + 6.0, 0.0),
        ):
            lean = -SIDES[support] * amount
            h.cog(
                tt,
                tx=-5.0 * lean * power,
                ty=-3.0 * amount,
                rx=-0.1 * amount * power,
                tz=-2.0 * amount,
            )
            h.spine(
                tt, hips=(0.0, 0.1 * lean, 0.1 * lean), chest=(-0.05 * amount, 0.0, -0.1 * lean)
            )
            h.head(tt, rx=0.25 * amount, eyes=(0.0, -40.0 * amount, 0.0))
        for s in SIDES:
            swing = 1.0 if s == side else -1.0
            h.arm(strike, s, [(0.0, 0.5 * swing * power, -1.0), (0.0, -0.6, 0.0), (0.0, 0.0, -0.1)])
            h.hand(strike, s, "open", amount=0.6)
        h.leg(wind, support, roll=0.0, toe_twist=0.1 * power)
        h.leg(follow, support, roll=0.25 * power, toe_twist=0.0)
        t = down + 12.0
    end = t
    h.stand(end)
    h.polish([0.0, end])


@clips.train("Look Around", "looks around the room, head following the world")
def look_around(b: ClipBuilder) -> None:
    """Look around a room: head, eyes and chest turn, the head follows the world for a beat."""
    h = Human(b)
    first = b.sign()
    end = 84.0
    h.planted_feet(0.0, end)
    h.stand(0.0)
    h.stand(end)
    for t, (ry, rx, rz, chest, follow) in {
        0.0: (0.0, 0.0, 0.0, 0.0, 1.0),
        6.0: (0.3 * first, 0.05, 0.0, 0.1, 1.0),
        12.0: (0.9 * first, 0.0, 0.0, 0.25, 1.0),
        18.0: (0.95 * first, -0.2, 0.05, 0.3, 1.0),
        24.0: (1.0 * first, -0.3, 0.1, 0.3, 1.0),
        30.0: (0.3 * first, -0.45, 0.05, 0.1, 0.7),
        36.0: (-0.4 * first, -0.5, 0.0, 0.0, 0.5),
        44.0: (-0.9 * first, -0.1, -0.05, -0.25, 0.5),
        50.0: (-1.0 * first, 0.2, -0.1, -0.3, 0.5),
        58.0: (-0.9 * first, 0.4, -0.05, -0.25, 0.8),
        64.0: (-0.8 * first, 0.45, 0.0, -0.2, 1.0),
        74.0: (-0.2 * first, 0.1, 0.0, -0.05, 1.0),
        end: (0.0, 0.0, 0.0, 0.0, 1.0),
    }.items():
        ry = b.vary(ry, 0.1)
        h.head(
            t,
            rx=rx,
            ry=ry,
            rz=rz,
            follow=follow,
            eyes=(55.0 * math.sin(ry), -40.0 * rx, -20.0 * abs(math.sin(ry))),
        )
        h.spine(
            t,
            chest=(0.3 * rx * 0.5, chest * first * np.sign(ry) if ry else 0.0, 0.0),
            hips=(0.0, 0.1 * chest, 0.0),
        )
        h.cog(t, ry=0.1 * ry, tx=-1.0 * ry)
    for side in SIDES:
        h.arm(40.0, side, [(0.0, -0.15, -1.38), (0.0, -0.45, 0.0), (0.1, 0.0, -0.1)])
        h.hand(40.0, side, "relaxed", amount=1.3)
    h.polish([0.0, 40.0, end])


@clips.train("Point & Shrug", "points far off, then shrugs palms up")
def point_and_shrug(b: ClipBuilder) -> None:
    """Point at something far off, look, then shrug with both palms up."""
    h = Human(b)
    side, other = h.drawn_sides()
    point, hold, drop, shrug, end = 12.0, 30.0, 38.0, 50.0, 74.0
    h.planted_feet(0.0, end)
    h.stand(0.0)
    h.stand(end)
    h.arm(
        point, side, [(0.0, -1.2, -0.1), (0.0, -0.05, 0.0), (0.0, 0.0, 0.0)], clavicle=(-0.1, 0.05)
    )
    h.arm(
        hold, side, [(0.1, -1.25, 0.0), (0.0, -0.05, 0.0), (0.0, 0.05, 0.0)], clavicle=(-0.12, 0.06)
    )
    h.arm(
        18.0, side, [(0.0, -1.3, 0.05), (0.0, -0.1, 0.0), (0.0, 0.1, 0.0)], clavicle=(-0.15, 0.08)
    )
    h.arm(
        24.0,
        side,
        [(0.05, -1.22, -0.02), (0.0, -0.02, 0.0), (0.0, 0.0, 0.0)],
        clavicle=(-0.1, 0.05),
    )
    h.hand(point, side, "point")
    h.hand(18.0, side, "point", amount=1.05)
    h.hand(hold, side, "point", amount=0.95)
    h.hand(44.0, other, "relaxed", amount=1.2)
    h.hand(66.0, side, "relaxed", amount=0.8)
    h.arm(drop, side, [(0.0, -0.2, -1.3), (0.0, -0.5, 0.0), (0.0, 0.0, -0.1)])
    h.hand(drop, side, "relaxed")
    for s_ in SIDES:
        h.arm(
            shrug,
            s_,
            [(-0.6, -0.35, -1.2), (-1.2, -1.2, 0.0), (0.0, 0.2, 0.3)],
            clavicle=(-0.05, 0.3),
        )
        h.arm(
            shrug + 10.0,
            s_,
            [(-0.55, -0.3, -1.25), (-1.1, -1.1, 0.0), (0.0, 0.2, 0.25)],
            clavicle=(0.0, 0.05),
        )
        h.hand(shrug, s_, "open", amount=0.8)
    h.arm(drop, other, [(0.0, -0.1, -1.4), (0.0, -0.35, 0.0), (0.0, 0.0, -0.1)])
    toward = SIDES[side]
    for t, (ry, rz, amount) in {
        0.0: (0.0, 0.0, 0.0),
        point: (0.5, 0.0, 0.5),
        hold: (0.6, 0.0, 0.6),
        drop: (0.1, 0.0, 0.1),
        shrug: (0.0, 0.2, 1.0),
        shrug + 10.0: (0.0, 0.15, 0.4),
        end: (0.0, 0.0, 0.0),
    }.items():
        h.head(
            t,
            ry=toward * ry,
            rz=rz * b.sign() if t == shrug else rz,
            rx=-0.1 * amount,
            eyes=(50.0 * toward * ry, 5.0, 0.0),
            jaw=0.1 * (t == shrug),
        )
        h.spine(
            t,
            chest=(-0.05 * amount, 0.25 * toward * ry, 0.0),
            chest_t=(0.0, 2.0 * (t == shrug), 0.0),
        )
        h.cog(t, ry=0.1 * toward * ry, ty=-0.5 * amount)
    h.polish([0.0, end])


@clips.train("Side Step", "two steps to one side and back")
def side_step(b: ClipBuilder) -> None:
    """Two steps to one side and back, like making room in a queue."""
    h = Human(b)
    direction = b.sign()
    lead = "l" if direction > 0 else "r"
    trail = "r" if lead == "l" else "l"
    width = b.vary(18.0, 3.0)
    end = 76.0
    h.stand(0.0)
    h.stand(end)
    # lead foot out, trail foot follows; twice out, then once back with each foot
    moves = [
        (lead, 8.0, width),
        (trail, 18.0, width),
        (lead, 30.0, 2 * width - 12.0),
        (trail, 40.0, 2 * width - 12.0),
        (trail, 54.0, width - 6.0),
        (lead, 64.0, width - 6.0),
    ]
    placed = {lead: 0.0, trail: 0.0}
    since = {lead: 0.0, trail: 0.0}
    for side, lift, to in moves:
        land = lift + 6.0
        h.plant(side, since[side], lift, placed[side], 0.0, 0.0)
        out = SIDES[side] * direction  # stepping towards this foot's own side or across
        h.foot(
            lift + 3.0,
            side,
            tx=0.5 * (placed[side] + to) * out,
            ty=7.0,
            tz=b.vary(1.0, 1.0),
            rz=0.1 * out,
        )
        h.foot(land, side, rz=0.0)
        h.foot(lift, side, rz=0.0)
        h.leg(lift, side, roll=0.4, bank=0.0)
        h.leg(land, side, roll=0.0, bank=0.1 * out)
        placed[side], since[side] = to * out, land
    for side in SIDES:
        h.plant(side, since[side], end, placed[side], 0.0, 0.0)
    for t, x in (
        (0.0, 0.0),
        (8.0, -2.0),
        (18.0, 0.5 * width),
        (30.0, 0.6 * width),
        (40.0, width - 6.0),
        (54.0, width - 6.0),
        (64.0, 0.5 * width),
        (end, 0.4 * width),
    ):
        h.cog(t, tx=direction * x, ty=-2.0 * (0 < t < end), rz=0.03 * direction * (0 < t < end))
        h.spine(
            t,
            hips=(0.0, 0.0, -0.05 * direction * (0 < t < end)),
            chest=(0.0, 0.0, 0.04 * direction * (0 < t < end)),
        )
    for t in (18.0, 40.0, 64.0):
        for side in SIDES:
            h.arm(
                t,
                side,
                [
                    (0.0, -0.1, -1.32 + 0.05 * SIDES[side] * direction),
                    (0.0, -0.4, 0.0),
                    (0.0, 0.0, -0.1),
                ],
            )
        h.head(t, ry=0.3 * direction * (t < 50), eyes=(20.0 * direction, 0.0, 0.0))
    h.polish([0.0, end])


# --- test clips ------------------------------------------------------------------------------
@clips.test("Range of Motion", "arms, torso and legs to their extremes")
def range_of_motion(b: ClipBuilder) -> None:
    """A rig test: arms overhead and behind, torso bends and twists, legs kick high (FK)."""
    h = Human(b)
    t = 0.0
    h.stand(0.0)
    h.planted_feet(0.0, 40.0)
    poses = [
        ([(0.0, 0.0, 1.2), (0.0, 0.0, 0.3), (0.0, 0.0, 0.3)], (0.0, 0.3), (0.0, 0.0, 0.0)),
        ([(0.0, -1.6, -0.2), (0.0, -1.8, 0.0), (0.3, 0.0, 0.0)], (-0.3, 0.0), (0.6, 0.0, 0.0)),
        ([(1.2, 1.0, -1.0), (0.0, -0.2, 0.0), (-0.5, 0.5, 0.0)], (0.4, -0.2), (-0.3, 0.0, 0.0)),
        ([(0.0, 0.0, 0.6), (0.0, 0.0, 1.6), (0.0, 0.0, 0.6)], (0.0, 0.4), (0.0, 0.9, 0.0)),
        ([(-0.8, -0.8, -0.6), (0.0, -2.0, 0.0), (0.0, 0.6, -0.6)], (-0.2, 0.0), (0.0, -0.9, 0.3)),
    ]
    for arms, clavicle, torso in poses:
        t += 8.0
        for side in SIDES:
            h.arm(t, side, arms, clavicle=clavicle)
            h.hand(t, side, "fist" if t % 16 else "open")
        h.spine(
            t, chest=(torso[0], torso[1], torso[2]), hips=(0.3 * torso[0], -0.3 * torso[1], 0.0)
        )
        h.head(t, rx=-0.5 * torso[0], ry=0.8 * torso[1], rz=0.5 * torso[2])
        h.cog(t, ty=-5.0, rx=0.3 * torso[0])
    # high kicks in FK, one leg then the other
    for n, side in enumerate(("r", "l")):
        t0 = 48.0 + 18.0 * n
        h.plant(side, 40.0 if n == 0 else 54.0, t0, 0.0, 0.0, 0.0)
        h.ik_fk(t0, side, 1.0, limb="leg")
        h.ik_fk(t0 + 3.0, side, 0.0, limb="leg")
        h.fk_leg(t0, side, [(0.0, 0.0, 0.0)] * 4)
        h.fk_leg(
            t0 + 7.0, side, [(-1.7, 0.0, 0.3), (0.1, 0.0, 0.0), (0.8, 0.0, 0.0), (0.5, 0.0, 0.0)]
        )
        h.fk_leg(
            t0 + 12.0, side, [(0.8, 0.2, 0.6), (2.0, 0.0, 0.0), (-0.6, 0.0, 0.0), (-0.4, 0.0, 0.0)]
        )
        h.fk_leg(t0 + 16.0, side, [(0.0, 0.0, 0.0)] * 4)
        h.ik_fk(t0 + 16.0, side, 0.0, limb="leg")
        h.ik_fk(t0 + 18.0, side, 1.0, limb="leg")
        h.plant(side, t0 + 18.0, 90.0, 0.0, 0.0, 0.0)
        other = "l" if side == "r" else "r"
        h.cog(t0 + 7.0, tx=6.0 * SIDES[other], ty=-8.0, rx=-0.3)
        h.cog(t0 + 12.0, tx=6.0 * SIDES[other], ty=-4.0, rx=0.4)
    h.cog(90.0, tx=0.0, ty=0.0, rx=0.0)
    h.stand(90.0)


@clips.test("Swing Dance", "rock steps, kicks and spins, fast")
def swing_dance(b: ClipBuilder) -> None:
    """Lindy-style footwork: rock steps, triple steps, kicks and two fast spins."""
    h = Human(b)
    beat = 6.0
    spins = {4: 0.0, 8: b.vary(2.9, 0.15), 12: b.vary(-0.2, 0.15)}
    heading = 0.0
    for k in range(17):
        t = k * beat
        if k in spins:
            heading = spins[k]
        bounce = 1.0 if k % 2 else 0.0
        h.root(t, ry=heading)
        h.cog(
            t,
            ty=-8.0 - 5.0 * bounce,
            tx=5.0 * math.sin(k * 1.3),
            rz=0.12 * math.sin(k),
            rx=0.15 * bounce,
        )
        h.spine(
            t,
            hips=(0.1, 0.35 * math.sin(k * 1.7), 0.25 * math.cos(k)),
            chest=(-0.1 * bounce, -0.4 * math.sin(k * 1.7), -0.2 * math.cos(k)),
        )
        for side in SIDES:
            swing = math.sin(k * 1.1 + (0 if side == "l" else math.pi))
            h.arm(
                t,
                side,
                [
                    (0.3 * swing, -1.2 * swing, -0.3 + 0.6 * bounce),
                    (0.0, -1.6 - 0.3 * bounce, 0.4),
                    (0.0, 0.3 * swing, 0.2),
                ],
                clavicle=(0.2 * swing, 0.2 * bounce),
            )
            h.hand(t, side, "open" if bounce else "fist", amount=1.0)
            h.ik_fk(t, side, 0.0)
            lifted = (k % 4 == 1 and side == "l") or (k % 4 == 3 and side == "r")
            h.foot(
                t,
                side,
                tx=4.0 * math.cos(k),
                ty=22.0 if lifted else 0.0,
                tz=(25.0 if lifted else -10.0 * math.sin(k * 0.9)),
                rx=-0.4 if lifted else 0.0,
                ry=0.3 * math.sin(k),
            )
            h.leg(t, side, roll=0.9 if (not lifted and bounce) else -0.2 if lifted else 0.0)
        h.head(
            t, ry=0.6 * math.sin(k * 0.8), rz=0.2 * math.sin(k * 1.4), rx=-0.1, jaw=0.15 * bounce
        )


@clips.test("Tai Chi", "slow deep stance, arm circles, crane stand")
def tai_chi(b: ClipBuilder) -> None:
    """Slow form: sink into a horse stance, wide arm circles, weight shifts, a crane stand."""
    h = Human(b)
    h.stand(0.0)
    h.plant("l", 0.0, 12.0, 0.0, 0.0, 0.0)
    h.plant("r", 0.0, 40.0, 0.0, 0.0, 0.0)
    h.foot(18.0, "l", tx=12.0, ty=10.0, tz=4.0)
    h.plant("l", 24.0, 96.0, b.vary(26.0, 2.0), 0.0, 6.0)
    h.foot(24.0, "l", ry=0.4)
    h.foot(96.0, "l", ry=0.4)
    # crane: the right foot rises to the knee and comes down wide
    h.foot(52.0, "r", tx=6.0, ty=28.0, tz=20.0, rx=0.6)
    h.foot(64.0, "r", tx=8.0, ty=30.0, tz=22.0, rx=0.7)
    h.plant("r", 74.0, 110.0, -b.vary(22.0, 2.0), 0.0, -6.0)
    h.foot(74.0, "r", ry=-0.4)
    h.foot(110.0, "r", ry=-0.4)
    for t, (sink, shift, turn_) in {
        0.0: (0.0, 0.0, 0.0),
        12.0: (0.2, -1.0, 0.0),
        24.0: (0.7, 0.0, 0.2),
        40.0: (1.0, 0.8, 0.5),
        52.0: (0.4, -1.0, 0.2),
        64.0: (0.3, -1.0, -0.3),
        80.0: (1.0, 0.0, -0.5),
        96.0: (1.0, 0.6, 0.0),
        110.0: (0.9, 0.0, 0.0),
    }.items():
        h.cog(t, ty=-30.0 * sink, tx=10.0 * shift, ry=0.6 * turn_, rx=0.05 * sink)
        h.spine(
            t,
            hips=(-0.15 * sink, -0.3 * turn_, 0.05 * shift),
            chest=(-0.05, 0.6 * turn_, -0.05 * shift),
        )
        h.head(t, ry=0.5 * turn_, rx=0.05, eyes=(30.0 * turn_, -5.0, 0.0))
        for side in SIDES:
            h.knee(t, side, tx=12.0 * sink, tz=6.0 * sink)
    for k, t in enumerate(np.arange(8.0, 110.0, 10.0)):
        phase = k * 0.7
        for side in SIDES:
            s = 1.0 if side == "l" else -1.0
            h.arm(
                float(t),
                side,
                [
                    (
                        0.6 * math.sin(phase),
                        -1.3 - 0.4 * math.cos(phase + s),
                        0.4 * math.sin(phase + s) - 0.2,
                    ),
                    (0.0, -0.9 - 0.4 * math.sin(phase), 0.3),
                    (0.5 * math.cos(phase), 0.0, 0.6 * math.sin(phase)),
                ],
            )
            h.hand(float(t), side, "open", amount=0.6 + 0.3 * math.sin(phase))
    h.stand(110.0, arms=True, hands=None)


LIBRARY = clips.library("biped")
