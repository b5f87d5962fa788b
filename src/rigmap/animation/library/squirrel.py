"""The squirrel's motion library: squash, stretch, bend and look poses; exaggerated tests.

Keys go on all 36 controls of the cartoon squirrel (centimetres, radians, slider
factors): whole-body ``body.*`` lattice deformers (squash > 0 stretches tall, < 0
squashes flat), the neck and head chain (``neck.bend`` > 0 bends the neck forward,
which the rig's collision corrective answers by sinking the chest under the teeth),
ears, arms, cheeks and a five-segment tail with curl and fluff. Every key pose keys
every control, as an animator keys a whole cartoon character; the tail's per-segment
keys carry overlap (each segment lags the one before). Test clips push the body
deformers to the ends of their soft ranges, fast.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rigmap.animation.library import Clips
from rigmap.animation.library.clip_builder import ClipBuilder

TAIL_SEGMENTS = 5
REST: dict[str, float] = {
    "root.tx": 0.0, "root.ty": 0.0, "root.tz": 0.0, "root.ry": 0.0,
    "body.bend_forward": 0.0, "body.bend_side": 0.0, "body.twist": 0.0, "body.squash": 0.0,
    "neck.bend": 0.0, "head.rx": 0.0, "head.ry": 0.0, "head.rz": 0.0, "head.squash": 0.0,
    "cheeks.puff": 0.0, "ear_l.rx": 0.0, "ear_r.rx": 0.0, "arm_l.rx": 0.0, "arm_r.rx": 0.0,
    "tail.curl": 0.0, "tail.fluff": 0.0,
}  # fmt: skip
for _segment in ("neck_1", "neck_2"):
    REST.update({f"{_segment}.r{a}": 0.0 for a in "xyz"})


@dataclass(frozen=True)
class Squirrel:
    """Keys whole poses of the squirrel; the tail's segments follow with overlap."""

    b: ClipBuilder

    def pose(
        self,
        frame: float,
        *,
        look=(0.0, 0.0, 0.0),
        tail_sway: float = 0.0,
        tail_lift: float = 0.0,
        tail_phase: float = 0.0,
        jitter: float = 0.03,
        interpolation: str = "bezier",
        **values: float,
    ) -> None:
        """Key every control at ``frame``.

        ``values`` uses ``control__channel`` names (``body__squash=0.3``); ``look`` =
        (up/down, left/right, tilt) spread over neck_1, neck_2 and head; the tail sways
        as a wave (``tail_sway`` amplitude, ``tail_phase`` its phase) and lifts.
        """
        b = self.b
        pose = dict(REST)
        pitch, turn, tilt = look
        for name, share in (("neck_1", 0.3), ("neck_2", 0.3), ("head", 0.4)):
            pose[f"{name}.rx"] += share * pitch
            pose[f"{name}.ry"] += share * turn
            pose[f"{name}.rz"] += share * tilt
        for k in range(TAIL_SEGMENTS):
            pose[f"tail_{k + 1}.rx"] = tail_lift * (1.0 - k / TAIL_SEGMENTS)
            pose[f"tail_{k + 1}.ry"] = tail_sway * math.sin(tail_phase - 0.7 * k)
        for name, value in values.items():
            control = name.replace("__", ".")
            if control not in pose:
                raise KeyError(f"squirrel pose: no control {control!r}")
            pose[control] = value if control.startswith("root.") else pose[control] + value
        for control, value in pose.items():
            if not control.startswith("root.") and jitter:
                value = b.vary(value, jitter)
            b.key(control, frame, _clamped(control, value), interpolation)


# soft ranges of the rig (cm, rad, factors): keys stay inside them
RANGES = {
    "root.tx": (-30, 30), "root.ty": (-10, 30), "root.tz": (-30, 30), "root.ry": (-3.14, 3.14),
    "body.bend_forward": (-0.6, 0.9), "body.bend_side": (-0.6, 0.6), "body.twist": (-0.7, 0.7),
    "body.squash": (-0.4, 0.4), "neck.bend": (-0.6, 1.4), "head.rx": (-0.7, 0.9),
    "head.ry": (-0.9, 0.9), "head.rz": (-0.5, 0.5), "head.squash": (-0.35, 0.35),
    "cheeks.puff": (0.0, 1.0), "ear_l.rx": (-0.5, 0.9), "ear_r.rx": (-0.5, 0.9),
    "arm_l.rx": (-1.2, 0.8), "arm_r.rx": (-1.2, 0.8), "tail.curl": (-0.6, 1.0),
    "tail.fluff": (0.0, 1.0),
}  # fmt: skip
for _segment in ("neck_1", "neck_2"):
    RANGES.update(
        {
            f"{_segment}.rx": (-0.6, 0.8),
            f"{_segment}.ry": (-0.7, 0.7),
            f"{_segment}.rz": (-0.4, 0.4),
        }
    )
for _k in range(1, TAIL_SEGMENTS + 1):
    RANGES.update({f"tail_{_k}.rx": (-0.7, 0.7), f"tail_{_k}.ry": (-0.7, 0.7)})


def _clamped(control: str, value: float) -> float:
    lo, hi = RANGES[control]
    return min(max(value, lo), hi)


# this library's clip functions, in corpus order (see rigmap.animation.library.Clips)
clips = Clips()


# --- training clips -------------------------------------------------------------------------


@clips.train("Hop", "three hops forward with squash and stretch")
def hop(b: ClipBuilder) -> None:
    """Three hops forward: squash to anticipate, stretch in the air, squash on landing."""
    sq = Squirrel(b)
    height = b.vary(12.0, 2.5)
    z, x, heading = -24.0, 0.0, 0.0
    veer = b.vary(0.0, 0.25)
    sq.pose(0.0, root__tz=z)
    t = 6.0
    for _ in range(3):
        step = b.vary(16.0, 2.0)
        sq.pose(
            t,
            root__tz=z,
            root__tx=x,
            root__ry=heading,
            body__squash=-0.25,
            body__bend_forward=0.25,
            look=(0.2, 0, 0),
            arm_l__rx=0.3,
            arm_r__rx=0.3,
            tail_lift=-0.2,
            tail__curl=0.3,
            ear_l__rx=-0.2,
            ear_r__rx=-0.2,
        )
        heading += veer
        sq.pose(
            t + 4.0,
            root__tz=z + 0.35 * step,
            root__tx=x + 0.35 * step * math.sin(heading),
            root__ry=heading - 0.5 * veer,
            root__ty=0.7 * height,
            body__squash=0.3,
            body__bend_forward=-0.15,
            look=(-0.2, 0, 0),
            arm_l__rx=-0.6,
            arm_r__rx=-0.6,
            tail_lift=0.3,
            tail__curl=-0.2,
            ear_l__rx=0.4,
            ear_r__rx=0.4,
            tail__fluff=0.4,
        )
        sq.pose(
            t + 7.0,
            root__tz=z + 0.7 * step,
            root__tx=x + 0.7 * step * math.sin(heading),
            root__ry=heading,
            root__ty=height,
            body__squash=0.15,
            look=(0.0, 0, 0),
            arm_l__rx=-0.3,
            arm_r__rx=-0.3,
            tail_lift=0.4,
            tail__curl=0.2,
            tail__fluff=0.6,
        )
        z += step * math.cos(heading)
        x += step * math.sin(heading)
        sq.pose(
            t + 11.0,
            root__tz=z,
            root__tx=x,
            root__ry=heading,
            body__squash=-0.3,
            body__bend_forward=0.2,
            look=(0.3, 0, 0),
            head__squash=-0.15,
            arm_l__rx=0.4,
            arm_r__rx=0.4,
            tail_lift=-0.3,
            tail__curl=0.5,
            cheeks__puff=0.3,
            ear_l__rx=0.6,
            ear_r__rx=0.6,
        )
        t += 16.0
    sq.pose(t + 2.0, root__tz=z, root__tx=x, root__ry=heading, look=(0.0, b.vary(0.3, 0.2), 0.0))
    sq.pose(t + 10.0, root__tz=z, root__tx=x, root__ry=heading, look=(-0.1, b.vary(0.3, 0.2), 0.1))


@clips.train("Look Around", "head darts left, right and up; ears swivel")
def look_around(b: ClipBuilder) -> None:
    """Sitting up, head darting left and right and up, ears swivelling, tail flicking."""
    sq = Squirrel(b)
    side = b.sign()
    for t, (pitch, turn, tilt, ears) in {
        0.0: (0.0, 0.0, 0.0, 0.0),
        8.0: (0.0, 0.7 * side, 0.1, 0.5),
        16.0: (-0.2, 0.8 * side, 0.25, 0.7),
        22.0: (-0.2, 0.7 * side, 0.2, 0.6),
        28.0: (0.1, -0.7 * side, -0.1, 0.4),
        38.0: (0.0, -0.85 * side, -0.3, 0.8),
        46.0: (-0.6, -0.2 * side, 0.0, 0.9),
        56.0: (-0.55, 0.1 * side, 0.3, 0.9),
        66.0: (0.0, 0.0, 0.0, 0.2),
    }.items():
        sq.pose(
            t,
            look=(pitch, turn, tilt),
            body__twist=0.25 * turn,
            body__squash=0.1 * ears,
            ear_l__rx=ears,
            ear_r__rx=ears * b.factor(0.3),
            tail_sway=0.3,
            tail_phase=t / 5.0,
            tail__curl=0.2,
            body__bend_side=-0.1 * tilt,
        )


@clips.train("Nibble", "bends to a nut, sits up and nibbles")
def nibble(b: ClipBuilder) -> None:
    """Bend down to a nut, pick it up in both paws, sit up and nibble (cheeks puffing)."""
    sq = Squirrel(b)
    sq.pose(0.0)
    sq.pose(
        10.0,
        body__bend_forward=0.5,
        neck__bend=0.6,
        look=(0.4, 0, 0),
        arm_l__rx=-0.2,
        arm_r__rx=-0.2,
        tail_lift=0.2,
    )
    sq.pose(
        18.0,
        body__bend_forward=0.75,
        neck__bend=1.2,
        look=(0.5, 0, 0),
        arm_l__rx=-0.5,
        arm_r__rx=-0.5,
        body__squash=-0.1,
        tail_lift=0.3,
    )
    sq.pose(
        24.0,
        body__bend_forward=0.7,
        neck__bend=1.1,
        look=(0.45, 0.1, 0),
        arm_l__rx=-0.9,
        arm_r__rx=-0.9,
        tail_lift=0.3,
    )
    sq.pose(
        34.0,
        body__bend_forward=0.15,
        neck__bend=0.5,
        look=(0.4, 0, 0),
        arm_l__rx=-1.0,
        arm_r__rx=-1.0,
        tail__curl=0.4,
    )
    for k in range(int(b.vary(6.0, 1.0))):
        t = 40.0 + 5.0 * k
        chew = k % 2
        sq.pose(
            t,
            body__bend_forward=0.15,
            neck__bend=0.7 + 0.15 * chew,
            look=(0.5 + 0.1 * chew, b.vary(0.0, 0.15), b.vary(0.0, 0.1)),
            arm_l__rx=-1.05,
            arm_r__rx=-1.05,
            cheeks__puff=0.4 + 0.4 * chew,
            head__squash=-0.08 * chew,
            tail__curl=0.4,
            tail_sway=0.15,
            tail_phase=t / 4,
        )
    end = 40.0 + 5.0 * 6 + 8.0
    sq.pose(
        end,
        body__bend_forward=0.0,
        neck__bend=0.1,
        arm_l__rx=-0.4,
        arm_r__rx=-0.4,
        cheeks__puff=0.6,
        tail__curl=0.3,
    )


@clips.train("Stretch Up", "stretches tall and alert, relaxes")
def stretch_up(b: ClipBuilder) -> None:
    """Alert: stretch up tall on the hind legs, ears up, look far; then relax down."""
    sq = Squirrel(b)
    sq.pose(0.0)
    sq.pose(8.0, body__squash=-0.15, body__bend_forward=0.1, ear_l__rx=-0.3, ear_r__rx=-0.3)
    sq.pose(
        16.0,
        body__squash=0.35,
        body__bend_forward=-0.3,
        look=(-0.4, 0, 0),
        ear_l__rx=0.8,
        ear_r__rx=0.8,
        arm_l__rx=0.5,
        arm_r__rx=0.5,
        tail_lift=-0.3,
        tail__fluff=0.8,
        head__squash=0.1,
    )
    sq.pose(
        30.0,
        body__squash=0.38,
        body__bend_forward=-0.35,
        look=(-0.5, b.vary(0.3, 0.2), 0),
        ear_l__rx=0.9,
        ear_r__rx=0.85,
        arm_l__rx=0.6,
        arm_r__rx=0.55,
        tail_lift=-0.3,
        tail__fluff=1.0,
    )
    sq.pose(
        42.0,
        body__squash=0.3,
        body__bend_forward=-0.3,
        look=(-0.3, -0.4, 0.2),
        ear_l__rx=0.7,
        ear_r__rx=0.9,
        tail__fluff=0.9,
    )
    sq.pose(54.0, body__squash=-0.05, body__bend_forward=0.05, tail__fluff=0.3)
    sq.pose(62.0)


@clips.train("Side Bend & Twist", "looks behind over each shoulder")
def side_bend_twist(b: ClipBuilder) -> None:
    """Look behind over one shoulder, then the other: body twists and bends sideways."""
    sq = Squirrel(b)
    side = b.sign()
    sq.pose(0.0)
    for t, amount in (
        (10.0, 0.6),
        (20.0, 1.0),
        (28.0, 0.9),
        (38.0, -0.6),
        (48.0, -1.0),
        (56.0, -0.9),
        (66.0, 0.0),
    ):
        s = side * amount
        sq.pose(
            t,
            body__twist=0.55 * s,
            body__bend_side=0.35 * s,
            look=(0.0, 0.7 * s, 0.2 * s),
            arm_l__rx=-0.3 * abs(s),
            arm_r__rx=0.2 * abs(s),
            tail_sway=0.4 * abs(s),
            tail_phase=1.5 * s,
            tail__curl=0.3,
            ear_l__rx=0.3,
            ear_r__rx=0.3,
        )


@clips.train("Tail Flick", "tail flicks in waves and fluffs up")
def tail_flick(b: ClipBuilder) -> None:
    """Sitting, the tail flicks in waves and fluffs up; the body answers a little."""
    sq = Squirrel(b)
    sq.pose(0.0)
    for k in range(10):
        t = 4.0 + 5.0 * k
        sq.pose(
            t,
            tail_sway=b.vary(0.6, 0.1),
            tail_phase=1.9 * k,
            tail_lift=0.3 * (k % 2),
            tail__curl=0.6 if k % 2 else -0.2,
            tail__fluff=0.3 + 0.6 * (k % 3 == 0),
            body__bend_side=0.08 * (1 if k % 2 else -1),
            body__squash=0.05 * (k % 2),
            look=(0.0, 0.2 * math.sin(k), 0.0),
            ear_l__rx=0.4,
            ear_r__rx=0.4,
        )
    sq.pose(60.0, tail__curl=0.2)


@clips.train("Groom", "paws rub the face, head shake")
def groom(b: ClipBuilder) -> None:
    """Grooming: paws rub the face, head tilts into them, a shake of the head."""
    sq = Squirrel(b)
    sq.pose(0.0)
    for k in range(6):
        t = 8.0 + 5.0 * k
        up = k % 2
        sq.pose(
            t,
            arm_l__rx=-1.1 + 0.3 * up,
            arm_r__rx=-1.0 + 0.3 * (1 - up),
            look=(0.3, 0.0, 0.25 * (1 if up else -1)),
            neck__bend=0.4,
            body__bend_forward=0.2,
            head__squash=-0.1 * up,
            ear_l__rx=-0.3,
            ear_r__rx=-0.3,
        )
    for k in range(4):
        t = 42.0 + 3.0 * k
        sq.pose(
            t,
            look=(0.0, 0.5 * (1 if k % 2 else -1), 0.3 * (1 if k % 2 else -1)),
            ear_l__rx=0.6 * (k % 2),
            ear_r__rx=0.6 * (1 - k % 2),
            tail__fluff=0.7,
        )
    sq.pose(60.0, tail__fluff=0.2)


@clips.train("Startle", "flinches, jumps back, freezes upright")
def startle(b: ClipBuilder) -> None:
    """A noise: flinch down, jump back, freeze upright, then relax."""
    sq = Squirrel(b)
    sq.pose(0.0)
    sq.pose(
        4.0, body__squash=-0.3, look=(0.2, 0, 0), ear_l__rx=-0.4, ear_r__rx=-0.4, tail__fluff=0.8
    )
    away = b.vary(0.0, 8.0)
    sq.pose(
        8.0,
        root__ty=8.0,
        root__tz=-10.0,
        root__tx=0.5 * away,
        root__ry=0.1 * away / 8.0,
        body__squash=0.3,
        body__bend_forward=-0.4,
        look=(-0.3, 0, 0),
        tail__fluff=1.0,
        tail_lift=0.5,
        arm_l__rx=-0.6,
        arm_r__rx=-0.6,
    )
    sq.pose(
        13.0,
        root__tz=-14.0,
        root__tx=away,
        root__ry=0.2 * away / 8.0,
        body__squash=-0.2,
        tail__fluff=1.0,
        tail__curl=0.6,
    )
    sq.pose(
        20.0,
        root__tz=-14.0,
        root__tx=away,
        root__ry=0.2 * away / 8.0,
        body__squash=0.3,
        look=(-0.3, 0.5 * b.sign(), 0.0),
        ear_l__rx=0.9,
        ear_r__rx=0.9,
        tail__fluff=1.0,
        arm_l__rx=0.4,
        arm_r__rx=0.4,
    )
    sq.pose(
        36.0,
        root__tz=-14.0,
        root__tx=away,
        root__ry=0.2 * away / 8.0,
        body__squash=0.28,
        look=(-0.3, 0.45 * b.sign(), 0.1),
        ear_l__rx=0.85,
        ear_r__rx=0.9,
        tail__fluff=0.9,
        arm_l__rx=0.35,
        arm_r__rx=0.4,
    )
    sq.pose(50.0, root__tz=-14.0, root__tx=away, root__ry=0.2 * away / 8.0, tail__fluff=0.2)


@clips.train("Dig", "digs to bury a nut, looks around, pats it down")
def dig(b: ClipBuilder) -> None:
    """Digging to bury a nut: bent over, paws scooping in turn, a look around, patting down."""
    sq = Squirrel(b)
    sq.pose(0.0)
    sq.pose(8.0, body__bend_forward=0.6, neck__bend=0.5, look=(0.5, 0, 0), tail_lift=0.4)
    for k in range(round(b.vary(7.0, 1.0))):
        t = 12.0 + 4.0 * k
        left = k % 2 == 0
        sq.pose(
            t,
            body__bend_forward=0.65,
            neck__bend=0.55,
            look=(0.5, 0.1 * (1 if left else -1), 0),
            arm_l__rx=-0.9 if left else 0.3,
            arm_r__rx=0.3 if left else -0.9,
            body__bend_side=0.08 * (1 if left else -1),
            tail_lift=0.45,
            tail__curl=-0.3,
            tail_sway=0.2,
            tail_phase=t / 3.0,
        )
    sq.pose(
        46.0,
        body__bend_forward=0.2,
        body__squash=0.2,
        look=(-0.2, 0.6 * b.sign(), 0.1),
        ear_l__rx=0.8,
        ear_r__rx=0.8,
        tail__fluff=0.6,
    )
    sq.pose(
        54.0,
        body__bend_forward=0.55,
        neck__bend=0.5,
        look=(0.5, 0, 0),
        arm_l__rx=-0.6,
        arm_r__rx=-0.6,
    )
    sq.pose(
        58.0,
        body__bend_forward=0.6,
        neck__bend=0.55,
        look=(0.55, 0, 0),
        arm_l__rx=0.2,
        arm_r__rx=0.2,
        body__squash=-0.1,
    )
    sq.pose(
        62.0,
        body__bend_forward=0.55,
        neck__bend=0.5,
        look=(0.5, 0, 0),
        arm_l__rx=-0.6,
        arm_r__rx=-0.6,
    )
    sq.pose(72.0, tail__curl=0.3)


# --- test: exaggerated -------------------------------------------------------------------------
@clips.test(
    "Exaggerated Squash & Stretch", "huge fast hops and spins at the ends of squash and stretch"
)
def exaggerated_squash_stretch(b: ClipBuilder) -> None:
    """Huge, fast hops with spins: the body at the ends of squash and stretch each beat."""
    sq = Squirrel(b)
    sq.pose(0.0)
    turn = 0.0
    for k in range(5):
        t = 3.0 + 8.0 * k
        turn += b.vary(1.2, 0.2) * (1 if k % 2 == 0 else -0.6)
        sq.pose(
            t,
            body__squash=-0.4,
            body__bend_forward=0.6,
            neck__bend=0.8,
            look=(0.6, 0, 0),
            head__squash=-0.35,
            root__ry=turn - 0.6,
            arm_l__rx=0.8,
            arm_r__rx=0.8,
            tail__curl=1.0,
            tail_lift=-0.5,
            cheeks__puff=1.0,
            ear_l__rx=-0.5,
            ear_r__rx=-0.5,
        )
        sq.pose(
            t + 4.0,
            root__ty=28.0,
            root__ry=turn,
            body__squash=0.4,
            body__bend_forward=-0.6,
            look=(-0.6, 0, 0),
            head__squash=0.35,
            arm_l__rx=-1.2,
            arm_r__rx=-1.2,
            tail__curl=-0.6,
            tail_lift=0.7,
            tail__fluff=1.0,
            ear_l__rx=0.9,
            ear_r__rx=0.9,
            body__twist=0.7 * (1 if k % 2 else -1),
        )
    sq.pose(46.0, body__squash=-0.4, head__squash=-0.35, root__ry=turn)
    sq.pose(52.0, root__ry=turn)


@clips.test(
    "Exaggerated Bend & Twist", "full bends and twists with the neck folded and thrown back"
)
def exaggerated_bend_twist(b: ClipBuilder) -> None:
    """Contortions: full forward bend with the neck folded, full twists, head thrown back."""
    sq = Squirrel(b)
    sq.pose(0.0)
    for t, (fwd, side, twist, neck, look) in {
        5.0: (0.9, 0.0, 0.0, 1.4, (0.8, 0.0, 0.0)),
        11.0: (0.9, 0.6, 0.7, 1.4, (0.8, 0.9, 0.5)),
        17.0: (-0.6, -0.6, -0.7, -0.6, (-0.7, -0.9, -0.5)),
        23.0: (-0.6, 0.6, 0.7, -0.6, (-0.7, 0.9, 0.5)),
        29.0: (0.9, -0.6, -0.7, 1.4, (0.9, -0.9, -0.5)),
        35.0: (0.0, 0.6, -0.7, 0.5, (0.0, 0.9, -0.5)),
        42.0: (0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0)),
    }.items():
        sq.pose(
            t,
            body__bend_forward=fwd,
            body__bend_side=side,
            body__twist=twist,
            neck__bend=neck,
            look=look,
            tail_sway=0.7,
            tail_phase=t,
            tail__curl=fwd,
            head__squash=0.3 * side,
            arm_l__rx=-1.2 * (fwd > 0),
            arm_r__rx=0.8 * (fwd > 0),
            cheeks__puff=abs(side),
            ear_l__rx=0.9 * (side > 0) - 0.5 * (side < 0),
            ear_r__rx=0.9 * (side < 0) - 0.5 * (side > 0),
            tail__fluff=abs(twist),
        )


LIBRARY = clips.library("squirrel")
