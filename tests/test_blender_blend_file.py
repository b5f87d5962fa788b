"""A user's own .blend as a rig (``blend_file``): a small armature made by Blender here.

The arm lies along Blender's +X, which stays +X in rigmap's Y-up axes.
"""

from __future__ import annotations

import subprocess
import textwrap

import numpy as np
import pytest

from rigmap.rigs import load
from rigmap.rigs.blender import find_blender

pytestmark = [
    pytest.mark.blender,
]

# A 3-bone arm along +X (1 m bones), quaternion rotations as Blender defaults them,
# a custom property, and a mesh deformed by the armature (downstream: pruned away).
MAKE_ARM = textwrap.dedent(
    """
    import sys
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    data = bpy.data.armatures.new("ArmData")
    arm = bpy.data.objects.new("Arm", data)
    bpy.context.scene.collection.objects.link(arm)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    parent = None
    for i, name in enumerate(["base", "upper", "lower"]):
        bone = data.edit_bones.new(name)
        bone.head, bone.tail = (float(i), 0.0, 0.0), (float(i + 1), 0.0, 0.0)
        bone.parent, bone.use_connect = parent, parent is not None
        parent = bone
    bpy.ops.object.mode_set(mode="OBJECT")
    arm.pose.bones["base"]["reach"] = 0.5
    arm.pose.bones["base"].id_properties_ui("reach").update(min=0.0, max=1.0)
    arm.pose.bones["lower"].lock_location = (True, True, True)
    mesh = bpy.data.objects.new("Skin", bpy.data.meshes.new("SkinMesh"))
    bpy.context.scene.collection.objects.link(mesh)
    mesh.modifiers.new("arm", "ARMATURE").object = arm
    bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
    """
)


@pytest.fixture(scope="module")
def arm_blend(tmp_path_factory):
    command = find_blender()
    if command.kind != "python":
        pytest.skip("making the test file needs the bpy Python environment")
    path = tmp_path_factory.mktemp("blend") / "arm.blend"
    subprocess.run(
        [str(command.executable), "-c", MAKE_ARM, str(path)], check=True, capture_output=True
    )
    return path


def test_user_armature_becomes_a_rig_in_centimetres_and_euler_radians(arm_blend):
    config = {
        "name": "blend_file",
        "path": str(arm_blend),
        "armature": "Arm",
        "cog_bone": "base",
        "exclude_bones": [],
        "used": ["base.r[xyz]", "upper.rz", "base.reach"],
        "workers": 1,
    }
    with load(config) as rig:
        assert rig.name == "blend_file:arm"
        assert rig.joint_names == ["base", "upper", "lower"]
        assert rig.parents.tolist() == [-1, 0, 1]
        assert rig.stats["euler_converted_bones"] == 3
        assert (
            "lower.tx" not in rig.controls and "lower.rx" in rig.controls
        )  # locked: not a control
        assert rig.controls["base.reach"].kind == "scalar"
        assert (rig.controls["base.reach"].lower, rig.controls["base.reach"].upper) == (0.0, 1.0)
        assert len(rig.used_controls) == 5

        c = rig.controls.index
        Y = rig.default_controls(3)
        Y[1, c("base.rz")] = np.pi / 2  # bones point along their own Y: this swings the arm
        Y[2, c("base.tx")] = 50.0  # cm along the bone's local X
        pose = rig.pose(Y)
    np.testing.assert_allclose(pose.positions[0], [[0, 0, 0], [100, 0, 0], [200, 0, 0]], atol=1e-4)
    np.testing.assert_allclose(pose.cog[0], [0, 0, 0], atol=1e-5)
    swung = pose.positions[1]
    np.testing.assert_allclose(np.linalg.norm(swung, axis=1), [0, 100, 200], atol=1e-3)
    # Blender's +Y (where the arm swung) is rigmap's -Z: Y up, the character facing +Z.
    np.testing.assert_allclose(swung[2], [0, 0, -200], atol=1e-3)
    bone_y = pose.cog_rotation[1][:, 1]  # a bone points along its own Y axis
    np.testing.assert_allclose(bone_y, swung[1] / 100, atol=1e-5)
    assert np.linalg.norm(pose.cog[2] - pose.cog[0]) == pytest.approx(50.0, abs=1e-4)
    np.testing.assert_allclose(pose.positions[2], pose.positions[0], atol=1e-4)  # COG-relative


def test_blend_file_needs_a_path_and_a_real_armature(arm_blend):
    with pytest.raises(ValueError, match="needs a 'path'"):
        load({"name": "blend_file"})
    from rigmap.rigs.blender import WorkerError

    with pytest.raises(WorkerError, match=r"armature object 'Rig' is missing.*\['Arm'\]"):
        load({"name": "blend_file", "path": str(arm_blend), "armature": "Rig", "workers": 1})
