"""The retarget script for the built-in ``quadruped`` (the paper's "Maya script", §6.1).

Written the way a TD scripts a dog rig: root and COG from the COG placement;
hips, chest and head oriented by the joints they carry; the spine's mid
control pulled onto the middle vertebrae; neck, tail, ears, jaw, scapulae and
toes aimed joint by joint; IK legs snapped to the paws with poles in the leg
planes, hock and toe tap from the target hock and toe; eye aim where the eyes
look; FK legs matched to the IK. Curl/wave attributes, roll and bank stay at
rest. Three read-backs of the rig (after the torso and IK, after the neck and
scapulae, after the head) give the parents' world frames.
"""

from __future__ import annotations

import numpy as np

from rigmap.retarget.chains import aim_chain
from rigmap.retarget.head import place_eye_aim, place_head
from rigmap.retarget.limbs import LimbLayout, match_limb_fk, place_ik_limb
from rigmap.retarget.scene import ScriptScene
from rigmap.retarget.torso import orient_hips, place_chest, place_root_and_cog, pull_spine_mid

SIDES = ("l", "r")
SPINE = ("pelvis", "spine_1", "spine_2", "spine_3", "spine_4", "spine_chest")
NECK = ("neck_1", "neck_2", "neck_3")
TAIL = tuple(f"tail_{i}" for i in range(1, 13))
TOES = 4


def _limbs(side: str) -> tuple[LimbLayout, LimbLayout]:
    front = LimbLayout(
        name=f"front_leg_{side}",
        upper=f"upper_arm_{side}",
        mid=f"forearm_{side}",
        end=f"wrist_{side}",
        ball=f"front_paw_{side}",
        toe=f"front_toe_{side}",
        fk_parent=f"scapula_{side}",
    )
    hind = LimbLayout(
        name=f"hind_leg_{side}",
        upper=f"thigh_{side}",
        mid=f"stifle_{side}",
        hock=f"hock_{side}",
        end=f"hind_paw_{side}",
        toe=f"hind_toe_{side}",
        fk_parent="pelvis",
    )
    return front, hind


LIMBS = tuple(limb for side in SIDES for limb in _limbs(side))
# where the toes of each paw hang from (the front paw joint; the hind foot's ball pivot)
TOE_PARENTS = {"front": "front_paw_{side}", "hind": "hind_leg_{side}:ball"}


def retarget_quadruped(scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray) -> None:
    """Write the quadruped's used controls into ``scene`` for its targets."""
    root = place_root_and_cog(scene, cog, cog_rotation)
    orient_hips(scene, cog_rotation, ("thigh_l", "thigh_r", "tail_1"))
    place_chest(scene, cog, cog_rotation, ("neck_1", "scapula_l", "scapula_r"))
    for limb in LIMBS:
        place_ik_limb(scene, root, limb)
    place_eye_aim(scene, root, [(f"eye_{s}", f"eye_end_{s}", f"eye_{s}_aim") for s in SIDES])

    torso = scene.evaluate()
    pull_spine_mid(scene, torso, SPINE, cog_rotation)
    aim_chain(
        scene, torso["spine_chest"], "spine_chest", [f"{j}_fk" for j in NECK], (*NECK[1:], "head")
    )
    aim_chain(scene, torso["pelvis"], "pelvis", [f"{j}_fk" for j in TAIL], (*TAIL[1:], "tail_tip"))
    for side in SIDES:
        aim_chain(
            scene,
            torso["spine_chest"],
            "spine_chest",
            [f"scapula_{side}_ctrl"],
            [f"upper_arm_{side}"],
        )

    body = scene.evaluate()
    place_head(
        scene,
        body,
        NECK[-1],
        ("head_end", "jaw", "eye_l", "eye_r", "ear_1_l", "ear_1_r"),
    )
    for limb in LIMBS:
        match_limb_fk(scene, body, limb)
    for side in SIDES:
        for end, parent_pattern in TOE_PARENTS.items():
            parent = parent_pattern.format(side=side)
            for k in range(1, TOES + 1):
                toe = f"{end}_toe_{side}_{k}"
                aim_chain(scene, body[parent], parent, [f"{toe}_fk"], [toe])

    head = scene.evaluate()
    aim_chain(scene, head["head"], "head", ["jaw_ctrl"], ["jaw_end"])
    for side in SIDES:
        ear = [f"ear_{i}_{side}" for i in (1, 2, 3)]
        aim_chain(
            scene, head["head"], "head", [f"{j}_fk" for j in ear], (*ear[1:], f"ear_tip_{side}")
        )
