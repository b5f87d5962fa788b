"""One retarget script for every built-in body rig, driven by a description of the body.

The biped's and the dog's "Maya scripts" (§6.1) solve the same chain of
constraints in the same order; only the joints differ. A :class:`BodyScript`
names them, and :meth:`BodyScript.run` solves, with three read-backs of the rig
giving the parents' world frames:

1. root and COG from the COG placement, hips and chest oriented by the joints
   they carry, IK limbs snapped to their ends with poles in the limb planes,
   eye aim where the eyes look; read back (``torso``);
2. the spine's mid control pulled onto the middle vertebrae and the
   :attr:`~BodyScript.torso_chains` (neck, clavicles or scapulae, a tail) aimed
   joint by joint; read back (``body``);
3. the head oriented by what it carries, FK limbs matched to the IK, the
   :attr:`~BodyScript.body_chains` (fingers, toes); read back (``head``);
4. the :attr:`~BodyScript.head_chains` (jaw, ears).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.retarget.chains import aim_chain
from rigmap.retarget.head import place_eye_aim, place_head
from rigmap.retarget.limbs import LimbLayout, match_limb_fk, place_ik_limb
from rigmap.retarget.scene import Readback, ScriptScene
from rigmap.retarget.torso import orient_hips, place_chest, place_root_and_cog, pull_spine_mid

SIDES = ("l", "r")


@dataclass(frozen=True)
class Chain:
    """FK ``controls`` hanging from joint ``parent``, each aimed at the joint in ``aims``."""

    parent: str
    controls: tuple[str, ...]
    aims: tuple[str, ...]

    @classmethod
    def of_joints(cls, parent: str, joints, tip: str) -> Chain:
        """The chain of ``joints``' FK controls (``<joint>_fk``), the last aimed at ``tip``."""
        joints = tuple(joints)
        return cls(parent, tuple(f"{j}_fk" for j in joints), (*joints[1:], tip))

    def solve(self, scene: ScriptScene, readback: Readback) -> None:
        aim_chain(scene, readback[self.parent], self.parent, self.controls, self.aims)


@dataclass(frozen=True)
class BodyScript:
    """The joints a body's retarget script reads: spine, what hips/chest/head carry, limbs,
    and the FK chains aimed after each read-back."""

    spine: tuple[str, ...]
    neck: tuple[str, ...]
    hips_carry: tuple[str, ...]
    chest_carry: tuple[str, ...]
    head_carry: tuple[str, ...]
    limbs: tuple[LimbLayout, ...]
    torso_chains: tuple[Chain, ...]
    body_chains: tuple[Chain, ...]
    head_chains: tuple[Chain, ...]

    def run(self, scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray) -> None:
        """Write the rig's used controls into ``scene`` for its targets."""
        root = place_root_and_cog(scene, cog, cog_rotation)
        orient_hips(scene, cog_rotation, self.hips_carry)
        place_chest(scene, cog, cog_rotation, self.chest_carry)
        for limb in self.limbs:
            place_ik_limb(scene, root, limb)
        place_eye_aim(scene, root, [(f"eye_{s}", f"eye_end_{s}", f"eye_{s}_aim") for s in SIDES])

        torso = scene.evaluate()
        pull_spine_mid(scene, torso, self.spine, cog_rotation)
        for chain in self.torso_chains:
            chain.solve(scene, torso)

        body = scene.evaluate()
        place_head(scene, body, self.neck[-1], self.head_carry)
        for limb in self.limbs:
            match_limb_fk(scene, body, limb)
        for chain in self.body_chains:
            chain.solve(scene, body)

        head = scene.evaluate()
        for chain in self.head_chains:
            chain.solve(scene, head)
