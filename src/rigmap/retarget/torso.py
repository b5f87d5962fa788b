"""Placement, COG, hips, chest and the spine's mid control from the COG and the torso joints.

The root (placement) control stands on the ground under the COG and faces the
body's heading; the COG control takes the rest of the COG's placement. Hips
and chest are orient constraints to joints they carry rigidly (the thighs,
the neck base and shoulders); the chest also moves to the chest joint. The
spine's mid control pulls the middle of the spine curve onto the middle
vertebrae.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rigmap.retarget.euler import matrix_to_euler
from rigmap.retarget.orient import principal_rotation, rotate, rotate_back
from rigmap.retarget.scene import Readback, ScriptScene, WorldTransform


def _in_space(space_R: np.ndarray, world_R: np.ndarray) -> np.ndarray:
    return np.swapaxes(space_R, -1, -2) @ world_R


def place_root_and_cog(
    scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray
) -> WorldTransform:
    """Root on the ground under the COG, turned to its heading; COG control for the rest.

    Returns the root's world transform (the space of IK, pole and aim controls).
    """
    forward = cog_rotation[:, :, 2]  # the body's +z
    heading = np.arctan2(forward[:, 0], forward[:, 2])
    root_R = principal_rotation(heading, "y")
    cog_offset = scene.rest_offset("cog", "root")
    root_t = cog - rotate(root_R, cog_offset)
    root_t[:, 1] = scene.rest["root"][1]  # the root's height is not keyed
    scene.set("root.tx", root_t[:, 0] - scene.rest["root"][0])
    scene.set("root.tz", root_t[:, 2] - scene.rest["root"][2])
    scene.set("root.ry", heading)
    scene.set_translation("cog", rotate_back(root_R, cog - root_t) - cog_offset)
    scene.set_euler(
        "cog", matrix_to_euler(_in_space(root_R, cog_rotation), scene.rotation_order("cog"))
    )
    return WorldTransform(root_R, root_t)


def orient_hips(scene: ScriptScene, cog_rotation: np.ndarray, carried: Sequence[str]) -> None:
    """Hips control from the joints the pelvis carries (thighs, tail base)."""
    world = scene.carried_orientation("pelvis", tuple(carried))
    scene.set_euler(
        "hips", matrix_to_euler(_in_space(cog_rotation, world), scene.rotation_order("hips"))
    )


def place_chest(
    scene: ScriptScene, cog: np.ndarray, cog_rotation: np.ndarray, carried: Sequence[str]
) -> None:
    """Chest control at the chest joint, oriented by the neck base and shoulders."""
    world = scene.carried_orientation("spine_chest", tuple(carried))
    scene.set_euler(
        "chest", matrix_to_euler(_in_space(cog_rotation, world), scene.rotation_order("chest"))
    )
    position = rotate_back(cog_rotation, scene.target("spine_chest") - cog)
    scene.set_translation("chest", position - scene.rest_offset("chest", "cog"))


def pull_spine_mid(
    scene: ScriptScene, readback: Readback, spine: Sequence[str], cog_rotation: np.ndarray
) -> None:
    """Move ``spine_mid`` so the spine curve passes through the middle vertebrae.

    ``readback`` is an evaluation with the mid control at rest. The mid
    control shifts the curve like a Bézier's two middle handles: fully at the
    middle (``4 s (1 − s)`` along the curve parameter ``s``), not at all at the
    ends; the shift is the least-squares fit of the interior joints' misses.
    """
    s = np.linspace(0.0, 1.0, len(spine))[1:-1]
    gain = 4.0 * s * (1.0 - s)
    miss = np.stack(
        [scene.target(j) - readback[j].t for j in spine[1:-1]], axis=1
    )  # (N, interior, 3)
    pull = np.einsum("k,nkd->nd", gain, miss) / np.sum(gain**2)
    scene.set_translation("spine_mid", rotate_back(cog_rotation, pull))
