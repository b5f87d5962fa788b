"""The built-in quadruped: a dog rig close to the paper's Marza dog (Table 3).

Centimetres, Y up, the dog faces +Z, +X is its left. Spline spine between hips
and chest, FK neck, head with follow blend, jaw, aimed eyes, curling ears, a
twelve-joint tail with curl and wave, scapulae, front legs with IK/FK and
reverse-foot roll, digitigrade hind legs (hock control), and four toes per paw
with curl/spread attributes.
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

TORSO = TorsoSpec(
    cog=(0, 60, -3),  # lying down lowers the body ~42 cm (the COG's ±60 cm range)
    hips=(0, 0, -27),
    chest=(0, 2, 25),
    spine_mid=(0, 1, -1),
    spine=("pelvis", "spine_1", "spine_2", "spine_3", "spine_4", "spine_chest"),
)
HEAD = HeadSpec(
    neck=((0, 66, 28), (0, 72, 34), (0, 78, 39)),
    head=(0, 83, 44),
    head_end=(0, 84, 63),
    jaw=(0, 80, 47),
    jaw_end=(0, 76, 61),
    jaw_open=0.7,
    eye_aim=(0, 87, 110),
    eye=(3.5, 87, 52),
    pupil=1.5,
)
TAIL_JOINTS = 12
TOES = 4


def build_quadruped():
    b = RigBuilder("quadruped")
    torso(b, TORSO)

    head(b, HEAD, parent="spine_chest", per_side=lambda side, sign: _ear(b, side, sign))

    tail = chain_attributes(b, "tail", group="tail", curl_range=(-2.5, 2.5))
    fk_chain(
        b,
        [f"tail_{i}" for i in range(1, TAIL_JOINTS + 1)],
        parent="pelvis",
        positions=[(0, 62 + 1.2 * k, -34 - 4.0 * k) for k in range(TAIL_JOINTS)],
        group="tail",
        used="rx ry",
        rotate_range=1.0,
        layer=tail,
        tip=(0, 62 + 1.2 * TAIL_JOINTS, -34 - 4.0 * TAIL_JOINTS),
        tip_name="tail_tip",
    )

    for side, sign in SIDES:
        _front_leg(b, side, sign)
        _hind_leg(b, side, sign)
    return TorchRig(
        b, description="Dog quadruped, digitigrade hind legs, tail and ears (cm, radians)"
    )


def _ear(b: RigBuilder, side: str, sign: float) -> None:
    """A curling ear of three FK joints on the head."""
    ear = chain_attributes(b, f"ear_{side}", group="head", curl_range=(-1.5, 1.5), side_sign=sign)
    fk_chain(
        b,
        [f"ear_{i}_{side}" for i in (1, 2, 3)],
        parent="head",
        joint_parent="head",
        positions=[mirror(p, sign) for p in ((5, 92, 45), (7, 97, 44), (9, 102, 43))],
        group="head",
        used="rx rz",
        rotate_range=1.2,
        layer=ear,
        tip=mirror((10, 107, 42), sign),
        tip_name=f"ear_tip_{side}",
    )


def _front_leg(b: RigBuilder, side: str, sign: float) -> None:
    fk_joint(
        b,
        f"scapula_{side}",
        parent="spine_chest",
        position=mirror((6, 66, 20), sign),
        group=f"front_leg_{side}",
        used="rx ry rz",
        rotate_range=0.5,
    )
    rest = {
        f"upper_arm_{side}": mirror((8, 52, 24), sign),
        f"forearm_{side}": mirror((8, 36, 17), sign),
        f"wrist_{side}": mirror((8, 12, 20), sign),
    }
    foot = FootSpec(
        heel=mirror((8, 1.0, 17), sign),
        ball=mirror((8, 3, 24), sign),
        toe=mirror((8, 0.5, 29), sign),
        half_width=3.0,
        ball_joint=f"front_paw_{side}",
        toe_joint=f"front_toe_{side}",
    )
    limb(
        b,
        f"front_leg_{side}",
        rest=rest,
        parent=f"scapula_{side}",
        side_sign=sign,
        foot=foot,
        usage=LimbUsage(fk="rx ry rz", attributes=("ik_fk",)),
    )
    _toes(
        b,
        f"front_paw_{side}",
        f"front_paw_{side}",
        side,
        sign,
        origin=(8, 2.0, 25),
        prefix=f"front_toe_{side}",
    )


def _hind_leg(b: RigBuilder, side: str, sign: float) -> None:
    rest = {
        f"thigh_{side}": mirror((7, 57, -30), sign),
        f"stifle_{side}": mirror((8, 38, -22), sign),
        f"hock_{side}": mirror((8, 18, -36), sign),
        f"hind_paw_{side}": mirror((8, 4, -31), sign),
    }
    foot = FootSpec(
        heel=mirror((8, 0.5, -34), sign),
        ball=mirror((8, 1.5, -28), sign),
        toe=mirror((8, 0.5, -24), sign),
        half_width=3.0,
        toe_joint=f"hind_toe_{side}",
    )
    limb(
        b,
        f"hind_leg_{side}",
        rest=rest,
        parent="pelvis",
        side_sign=sign,
        foot=foot,
        digitigrade=True,
        usage=LimbUsage(fk="rx ry rz", hock="rx", attributes=("ik_fk",)),
    )
    _toes(
        b,
        f"hind_leg_{side}:ball",
        f"hind_paw_{side}",
        side,
        sign,
        origin=(8, 1.5, -28),
        prefix=f"hind_toe_{side}",
    )


def _toes(
    b: RigBuilder, parent: str, parent_joint: str, side: str, sign: float, *, origin, prefix: str
) -> None:
    """Four toes fanned across the paw, one FK control each, curl/spread per paw."""
    attrs = chain_attributes(
        b,
        f"{prefix}s",
        group=f"paws_{side}",
        wave=False,
        side_sign=sign,
        used=("curl", "side_curl"),
        curl_range=(-0.8, 1.2),
    )
    origin = np.asarray(origin, float)
    for k, lateral in enumerate(np.linspace(-2.4, 2.4, TOES)):
        base = origin + np.array([lateral * 0.6, 0.0, 0.0])
        tip = origin + np.array([lateral, -1.0, 3.5 - 0.6 * abs(lateral)])
        # the control pivots at the paw, the joint is the toe's tip
        fk_chain(
            b,
            [f"{prefix}_{k + 1}"],
            parent=parent,
            joint_parent=parent_joint,
            positions=[mirror(base, sign)],
            group=f"paws_{side}",
            used="rx",
            rotate_range=0.9,
            layer=attrs,
            declare_joints=False,
            xform_prefix="toe_base:",
            tip=mirror(tip, sign),
            tip_name=f"{prefix}_{k + 1}",
        )
