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
from rigmap.rigs.features.aim import aim_joint
from rigmap.rigs.features.chain_attributes import chain_attributes
from rigmap.rigs.features.fixed_joint import fixed_joint
from rigmap.rigs.features.fk_chain import fk_chain
from rigmap.rigs.features.limb import FootSpec, LimbUsage, limb
from rigmap.rigs.features.space_blend import space_blend_control
from rigmap.rigs.features.spline_spine import spline_spine

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
SIDES = (("l", 1.0), ("r", -1.0))


def _mirror(point, sign: float) -> np.ndarray:
    p = np.asarray(point, dtype=np.float64).copy()
    p[0] *= sign
    return p


def build_biped():
    b = RigBuilder("biped")
    b.transform_control("root", parent=None, group="root", used="tx tz ry", translate_range=300.0)
    b.transform_control(
        "cog",
        parent="root",
        offset=(0, 100, 0),
        group="torso",
        used="tx ty tz rx ry rz",
        translate_range=60.0,  # crouching and kneeling lower the hips ~50 cm
    )
    b.transform_control(
        "hips", parent="cog", offset=(0, 0, 0), group="torso", used="rx ry rz", rotate_range=0.8
    )
    b.transform_control(
        "chest",
        parent="cog",
        offset=(0, 40, 0),
        group="torso",
        used="tx ty tz rx ry rz",
        rotate_range=1.0,
    )
    spine_mid = b.transform_control(
        "spine_mid",
        parent="cog",
        offset=(0, 20, 0),
        group="torso",
        used="tx ty tz",
        translate_range=15.0,
    )
    spine = ["pelvis", "spine_1", "spine_2", "spine_3", "spine_chest"]
    spline_spine(
        b, spine, hips="hips", chest="chest", mid=spine_mid, parent_joint=None, group="torso"
    )

    # neck and head: FK neck, head control following neck or world
    fk_chain(
        b,
        ["neck_1", "neck_2"],
        parent="spine_chest",
        positions=[(0, 148, 0), (0, 155, 1)],
        group="head",
        used="rx ry rz",
        rotate_range=0.8,
    )
    space_blend_control(
        b,
        "head",
        parent="neck_2",
        world_space="root",
        position=(0, 162, 2),
        group="head",
        used="rx ry rz",
    )
    b.joint("head", "neck_2")
    fixed_joint(b, "head_end", parent="head", position=(0, 180, 2))
    fk_chain(
        b,
        ["jaw"],
        parent="head",
        positions=[(0, 163, 5)],
        group="head",
        used="rx",
        rotate_range={"rx": (-0.1, 0.6), "ry": (-0.3, 0.3), "rz": (-0.2, 0.2)},
        control_suffix="_ctrl",
    )
    fixed_joint(b, "jaw_end", parent="jaw", position=(0, 156, 11))
    b.transform_control(
        "eye_aim",
        parent="root",
        offset=(0, 168, 70),
        group="head",
        used="tx ty tz",
        translate_range=60.0,
    )
    for side, sign in SIDES:
        eye = _mirror((3.2, 168, 8), sign)
        b.transform_control(
            f"eye_{side}_aim",
            parent="eye_aim",
            offset=_mirror((3.2, 0, 0), sign),
            group="head",
            used="",
            translate_range=10.0,
        )
        aim_joint(
            b,
            f"eye_{side}",
            f"eye_end_{side}",
            parent="head",
            target=f"eye_{side}_aim",
            position=eye,
            end_position=eye + np.array([0.0, 0.0, 1.2]),
        )

    for side, sign in SIDES:
        _arm(b, side, sign)
        _leg(b, side, sign)
    return b.build(description="Human biped, IK/FK limbs, spline spine, fingers (cm, radians)")


def _arm(b: RigBuilder, side: str, sign: float) -> None:
    group = f"arm_{side}"
    fk_chain(
        b,
        [f"clavicle_{side}"],
        parent="spine_chest",
        positions=[_mirror((2, 145, 2), sign)],
        group=group,
        used="ry rz",
        rotate_range=0.6,
        control_suffix="_ctrl",
    )
    rest = {
        f"upper_arm_{side}": _mirror((17, 146, -1), sign),
        f"forearm_{side}": _mirror((45, 146, -3), sign),
        f"hand_{side}": _mirror((70, 146, -1), sign),
    }
    limb(
        b,
        f"arm_{side}",
        joints=list(rest),
        rest=rest,
        parent=f"clavicle_{side}",
        parent_joint=f"clavicle_{side}",
        ik_space="root",
        pole_distance=40.0,
        group=group,
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
        positions = [_mirror(base + k * step, sign) for k in range(3)]
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
            tip=_mirror(base + 3 * step * 0.8, sign),
            tip_name=f"{finger}_tip_{side}",
        )


def _leg(b: RigBuilder, side: str, sign: float) -> None:
    group = f"leg_{side}"
    rest = {
        f"thigh_{side}": _mirror((9, 95, 0), sign),
        f"shin_{side}": _mirror((9, 52, 1.5), sign),
        f"foot_{side}": _mirror((9, 9, -1), sign),
    }
    foot = FootSpec(
        heel=_mirror((9, 0, -5), sign),
        ball=_mirror((9, 1.5, 12), sign),
        toe=_mirror((9, 1.5, 19), sign),
        half_width=4.5,
        ball_joint=f"ball_{side}",
        toe_joint=f"toe_{side}",
    )
    limb(
        b,
        f"leg_{side}",
        joints=list(rest),
        rest=rest,
        parent="pelvis",
        parent_joint="pelvis",
        ik_space="root",
        pole_distance=40.0,
        group=group,
        side_sign=sign,
        foot=foot,
        usage=LimbUsage(
            fk="rx ry rz",
            attributes=("ik_fk",),
            foot=("roll", "bank", "toe_tap", "heel_twist", "toe_twist"),
        ),
    )
