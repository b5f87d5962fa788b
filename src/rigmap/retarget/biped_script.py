"""The retarget script for the built-in ``biped`` (the paper's "Maya script", §6.1).

Root and COG from the COG placement; hips, chest, head and hands oriented by
the joints they carry; the spine's mid control pulled onto the middle
vertebrae; neck, clavicles, jaw and fingers aimed joint by joint; IK arms and
legs snapped to hands and ankles with poles in the limb planes, toe tap from
the target toe; eye aim where the eyes look; FK limbs matched to the IK.
Finger curl/spread, foot roll, bank and twists stay at rest. The solve is the
shared :class:`~rigmap.retarget.body_script.BodyScript`; this module names the
biped's joints.
"""

from __future__ import annotations

import numpy as np

from rigmap.retarget.body_script import SIDES, BodyScript, Chain
from rigmap.retarget.limbs import LimbLayout
from rigmap.retarget.scene import ScriptScene

SPINE = ("pelvis", "spine_1", "spine_2", "spine_3", "spine_chest")
NECK = ("neck_1", "neck_2")
FINGERS = ("thumb", "index", "middle", "ring", "pinky")


def _limbs(side: str) -> tuple[LimbLayout, LimbLayout]:
    fingers = [f"{finger}_1_{side}" for finger in FINGERS]
    arm = dict(name="arm", upper="upper_arm", mid="forearm", end="hand")
    leg = dict(name="leg", upper="thigh", mid="shin", end="foot", ball="ball", toe="toe")
    return (
        LimbLayout.sided(side, f"clavicle_{side}", carried=fingers, **arm),
        LimbLayout.sided(side, "pelvis", **leg),
    )


LIMBS = tuple(limb for side in SIDES for limb in _limbs(side))

BIPED = BodyScript(
    spine=SPINE,
    neck=NECK,
    hips_carry=("thigh_l", "thigh_r"),
    chest_carry=("neck_1", "clavicle_l", "clavicle_r"),
    head_carry=("head_end", "jaw", "eye_l", "eye_r"),
    limbs=LIMBS,
    torso_chains=(
        Chain.of_joints("spine_chest", NECK, "head"),
        *(
            Chain("spine_chest", (f"clavicle_{side}_ctrl",), (f"upper_arm_{side}",))
            for side in SIDES
        ),
    ),
    body_chains=tuple(
        Chain.of_joints(
            f"hand_{side}", [f"{finger}_{i}_{side}" for i in (1, 2, 3)], f"{finger}_tip_{side}"
        )
        for side in SIDES
        for finger in FINGERS
    ),
    head_chains=(Chain("head", ("jaw_ctrl",), ("jaw_end",)),),
)


def retarget_biped(scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray) -> None:
    """Write the biped's used controls into ``scene`` for its targets."""
    BIPED.run(scene, cog, cog_rotation)
