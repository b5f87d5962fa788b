"""The retarget script for the built-in ``quadruped`` (the paper's "Maya script", §6.1).

Written the way a TD scripts a dog rig: root and COG from the COG placement;
hips, chest and head oriented by the joints they carry; the spine's mid
control pulled onto the middle vertebrae; neck, tail, ears, jaw, scapulae and
toes aimed joint by joint; IK legs snapped to the paws with poles in the leg
planes, hock and toe tap from the target hock and toe; eye aim where the eyes
look; FK legs matched to the IK. Curl/wave attributes, roll and bank stay at
rest. The solve is the shared :class:`~rigmap.retarget.body_script.BodyScript`
(three read-backs: after the torso and IK, after the neck and scapulae, after
the head); this module names the dog's joints.
"""

from __future__ import annotations

import numpy as np

from rigmap.retarget.body_script import SIDES, BodyScript, Chain
from rigmap.retarget.limbs import LimbLayout
from rigmap.retarget.scene import ScriptScene

SPINE = ("pelvis", "spine_1", "spine_2", "spine_3", "spine_4", "spine_chest")
NECK = ("neck_1", "neck_2", "neck_3")
TAIL = tuple(f"tail_{i}" for i in range(1, 13))
TOES = 4


def _limbs(side: str) -> tuple[LimbLayout, LimbLayout]:
    front = dict(name="front_leg", upper="upper_arm", mid="forearm", end="wrist")
    hind = dict(name="hind_leg", upper="thigh", mid="stifle", hock="hock", end="hind_paw")
    return (
        LimbLayout.sided(side, f"scapula_{side}", ball="front_paw", toe="front_toe", **front),
        LimbLayout.sided(side, "pelvis", toe="hind_toe", **hind),
    )


LIMBS = tuple(limb for side in SIDES for limb in _limbs(side))
# where the toes of each paw hang from (the front paw joint; the hind foot's ball pivot)
TOE_PARENTS = {"front": "front_paw_{side}", "hind": "hind_leg_{side}:ball"}


def _toe(side: str, end: str, k: int) -> Chain:
    toe = f"{end}_toe_{side}_{k}"
    return Chain(TOE_PARENTS[end].format(side=side), (f"{toe}_fk",), (toe,))


QUADRUPED = BodyScript(
    spine=SPINE,
    neck=NECK,
    hips_carry=("thigh_l", "thigh_r", "tail_1"),
    chest_carry=("neck_1", "scapula_l", "scapula_r"),
    head_carry=("head_end", "jaw", "eye_l", "eye_r", "ear_1_l", "ear_1_r"),
    limbs=LIMBS,
    torso_chains=(
        Chain.of_joints("spine_chest", NECK, "head"),
        Chain.of_joints("pelvis", TAIL, "tail_tip"),
        *(
            Chain("spine_chest", (f"scapula_{side}_ctrl",), (f"upper_arm_{side}",))
            for side in SIDES
        ),
    ),
    body_chains=tuple(
        _toe(side, end, k) for side in SIDES for end in TOE_PARENTS for k in range(1, TOES + 1)
    ),
    head_chains=(
        Chain("head", ("jaw_ctrl",), ("jaw_end",)),
        *(
            Chain.of_joints("head", [f"ear_{i}_{side}" for i in (1, 2, 3)], f"ear_tip_{side}")
            for side in SIDES
        ),
    ),
)


def retarget_quadruped(scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray) -> None:
    """Write the quadruped's used controls into ``scene`` for its targets."""
    QUADRUPED.run(scene, cog, cog_rotation)
