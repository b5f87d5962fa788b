"""The built-in biped: a human rig close to the paper's "Stewart" (Table 3).

Centimetres, Y up, the character faces +Z, +X is its left. Built from the
feature units: placement/COG/hips/chest controls, a spline spine with tweaks,
FK neck, a head with a follow (space) blend, jaw, aimed eyes, clavicles, IK/FK
arms with poles, fingers with curl/spread attributes, IK/FK legs with
reverse-foot roll. Animators key about 200 of its ~670 channels.
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.engine.builder import RigBuilder
from rigmap.rigs.engine.torch_rig import TorchRig
from rigmap.rigs.features.chain_attributes import chain_attributes
from rigmap.rigs.features.fk_chain import fk_chain, fk_joint
from rigmap.rigs.features.head import HeadSpec, head
from rigmap.rigs.features.limb import FootSpec, LimbUsage, limb
from rigmap.rigs.features.sides import SIDES, mirror
from rigmap.rigs.features.torso import TorsoSpec, torso

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
TORSO = TorsoSpec(
    cog=(0, 100, 0),  # crouching and kneeling lower the hips ~50 cm (the COG's ±60 cm range)
    hips=(0, 0, 0),
    chest=(0, 40, 0),
    spine_mid=(0, 20, 0),
    spine=("pelvis", "spine_1", "spine_2", "spine_3", "spine_chest"),
)
HEAD = HeadSpec(
    neck=((0, 148, 0), (0, 155, 1)),
    head=(0, 162, 2),
    head_end=(0, 180, 2),
    jaw=(0, 163, 5),
    jaw_end=(0, 156, 11),
    jaw_open=0.6,
    eye_aim=(0, 168, 70),
    eye=(3.2, 168, 8),
    pupil=1.2,
)


def build_biped():
    b = RigBuilder("biped")
    torso(b, TORSO)

    # neck and head: FK neck, head control following neck or world, jaw, aimed eyes
    head(b, HEAD, parent="spine_chest")

    for side, sign in SIDES:
        _arm(b, side, sign)
        _leg(b, side, sign)
    return TorchRig(b, description="Human biped, IK/FK limbs, spline spine, fingers (cm, radians)")


def _arm(b: RigBuilder, side: str, sign: float) -> None:
    fk_joint(
        b,
        f"clavicle_{side}",
        parent="spine_chest",
        position=mirror((2, 145, 2), sign),
        group=f"arm_{side}",
        used="ry rz",
        rotate_range=0.6,
    )
    rest = {
        f"upper_arm_{side}": mirror((17, 146, -1), sign),
        f"forearm_{side}": mirror((45, 146, -3), sign),
        f"hand_{side}": mirror((70, 146, -1), sign),
    }
    limb(
        b,
        f"arm_{side}",
        rest=rest,
        parent=f"clavicle_{side}",
        side_sign=sign,
        usage=LimbUsage(fk="rx ry rz", attributes=("ik_fk",), ik_range=90.0),
    )
    # fingers: base positions on the hand, three joints each, curl + spread attributes
    bases = {
        "thumb": ((72, 145, 3), (3, -1, 3)),
        "index": ((78, 146, 2.5), (3.8, 0, 0)),
        "middle": ((79, 146, 0.5), (4.0, 0, 0)),
        "ring": ((78, 146, -1.5), (3.7, 0, 0)),
        "pinky": ((77, 146, -3.5), (3.0, 0, 0)),
    }
    for finger, (base, step) in bases.items():
        base = np.asarray(base, float)
        step = np.asarray(step, float)
        names = [f"{finger}_{i}_{side}" for i in (1, 2, 3)]
        positions = [mirror(base + k * step, sign) for k in range(3)]
        attrs = chain_attributes(
            b,
            f"{finger}_{side}",
            group=f"hand_{side}",
            side_curl=True,
            wave=False,
            used=("curl", "side_curl"),
            curl_range=(-0.5, 2.5),
            bend_axis="z" if finger != "thumb" else "y",
            side_axis="y" if finger != "thumb" else "z",
            # positive curl closes both hands towards the palm (down in the T-pose)
            bend_sign=-sign,
            side_sign=-sign,
        )
        fk_chain(
            b,
            names,
            parent=f"hand_{side}",
            positions=positions,
            group=f"hand_{side}",
            used="ry rz",
            rotate_range=1.6,
            layer=attrs,
            tip=mirror(base + 3 * step * 0.8, sign),
            tip_name=f"{finger}_tip_{side}",
        )


def _leg(b: RigBuilder, side: str, sign: float) -> None:
    rest = {
        f"thigh_{side}": mirror((9, 95, 0), sign),
        f"shin_{side}": mirror((9, 52, 1.5), sign),
        f"foot_{side}": mirror((9, 9, -1), sign),
    }
    foot = FootSpec(
        heel=mirror((9, 0, -5), sign),
        ball=mirror((9, 1.5, 12), sign),
        toe=mirror((9, 1.5, 19), sign),
        half_width=4.5,
        ball_joint=f"ball_{side}",
        toe_joint=f"toe_{side}",
    )
    limb(
        b,
        f"leg_{side}",
        rest=rest,
        parent="pelvis",
        side_sign=sign,
        foot=foot,
        usage=LimbUsage(
            fk="rx ry rz",
            attributes=("ik_fk",),
            foot=("roll", "bank", "toe_tap", "heel_twist", "toe_twist"),
        ),
    )
