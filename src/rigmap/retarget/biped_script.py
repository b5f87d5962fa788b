"""The retarget script for the built-in ``biped`` (the paper's "Maya script", §6.1).

Root and COG from the COG placement; hips, chest, head and hands oriented by
the joints they carry; the spine's mid control pulled onto the middle
vertebrae; neck, clavicles, jaw and fingers aimed joint by joint; IK arms and
legs snapped to hands and ankles with poles in the limb planes, toe tap from
the target toe; eye aim where the eyes look; FK limbs matched to the IK.
Finger curl/spread, foot roll, bank and twists stay at rest. Three read-backs
of the rig give the parents' world frames.
"""

from __future__ import annotations

import numpy as np

from rigmap.retarget.chains import aim_chain
from rigmap.retarget.head import place_eye_aim, place_head
from rigmap.retarget.limbs import LimbLayout, match_limb_fk, place_ik_limb
from rigmap.retarget.scene import ScriptScene
from rigmap.retarget.torso import orient_hips, place_chest, place_root_and_cog, pull_spine_mid

SIDES = ("l", "r")
SPINE = ("pelvis", "spine_1", "spine_2", "spine_3", "spine_chest")
NECK = ("neck_1", "neck_2")
FINGERS = ("thumb", "index", "middle", "ring", "pinky")


def _limbs(side: str) -> tuple[LimbLayout, LimbLayout]:
    arm = LimbLayout(
        name=f"arm_{side}",
        upper=f"upper_arm_{side}",
        mid=f"forearm_{side}",
        end=f"hand_{side}",
        carried=tuple(f"{finger}_1_{side}" for finger in FINGERS),
        fk_parent=f"clavicle_{side}",
    )
    leg = LimbLayout(
        name=f"leg_{side}",
        upper=f"thigh_{side}",
        mid=f"shin_{side}",
        end=f"foot_{side}",
        ball=f"ball_{side}",
        toe=f"toe_{side}",
        fk_parent="pelvis",
    )
    return arm, leg


LIMBS = tuple(limb for side in SIDES for limb in _limbs(side))


def retarget_biped(scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray) -> None:
    """Write the biped's used controls into ``scene`` for its targets."""
    root = place_root_and_cog(scene, cog, cog_rotation)
    orient_hips(scene, cog_rotation, ("thigh_l", "thigh_r"))
    place_chest(scene, cog, cog_rotation, ("neck_1", "clavicle_l", "clavicle_r"))
    for limb in LIMBS:
        place_ik_limb(scene, root, limb)
    place_eye_aim(scene, root, [(f"eye_{s}", f"eye_end_{s}", f"eye_{s}_aim") for s in SIDES])

    torso = scene.evaluate()
    pull_spine_mid(scene, torso, SPINE, cog_rotation)
    aim_chain(
        scene, torso["spine_chest"], "spine_chest", [f"{j}_fk" for j in NECK], (*NECK[1:], "head")
    )
    for side in SIDES:
        aim_chain(
            scene,
            torso["spine_chest"],
            "spine_chest",
            [f"clavicle_{side}_ctrl"],
            [f"upper_arm_{side}"],
        )

    body = scene.evaluate()
    place_head(scene, body, NECK[-1], ("head_end", "jaw", "eye_l", "eye_r"))
    for limb in LIMBS:
        match_limb_fk(scene, body, limb)
    for side in SIDES:
        hand = f"hand_{side}"
        for finger in FINGERS:
            joints = [f"{finger}_{i}_{side}" for i in (1, 2, 3)]
            aim_chain(
                scene,
                body[hand],
                hand,
                [f"{j}_fk" for j in joints],
                (*joints[1:], f"{finger}_tip_{side}"),
            )

    head = scene.evaluate()
    aim_chain(scene, head["head"], "head", ["jaw_ctrl"], ["jaw_end"])
