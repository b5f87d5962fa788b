"""The script baseline: constraint-based retargeting onto the rig's controls.

What a TD would script without rigmap: put an empty at every target joint
position, constrain controls to them (copy location, copy rotation, damped
track), let Blender solve, read each control's *visual* transform back as
channel values, remove the constraints. Runs inside Blender on a loaded
:class:`RigSession`; the rig is left as it was.
"""

from __future__ import annotations

import bpy
import numpy as np
from mathutils import Matrix, Vector
from rig_session import RigSession

CONSTRAINT_TYPES = ("COPY_LOCATION", "COPY_ROTATION", "COPY_TRANSFORMS", "DAMPED_TRACK")
NEEDS_ROTATION = ("COPY_ROTATION", "COPY_TRANSFORMS")
COG = "cog"
TAG = "rigmap_retarget"


def _check_mapping(session: RigSession, mapping: list[dict]) -> None:
    joints = set(session.joint_names)
    bones = session.rig.pose.bones
    for i, entry in enumerate(mapping):
        where = f"retarget mapping entry {i} ({entry})"
        if entry.get("type") not in CONSTRAINT_TYPES:
            raise ValueError(f"{where}: type must be one of {CONSTRAINT_TYPES}")
        if entry.get("bone") not in bones:
            raise ValueError(
                f"{where}: bone {entry.get('bone')!r} is not an evaluated bone of the rig "
                "(misspelt, or pruned because it cannot move the selected joints)"
            )
        target = entry.get("target")
        if target != COG and target not in joints:
            raise ValueError(f"{where}: target must be {COG!r} or a selected joint")
        if entry["type"] in NEEDS_ROTATION and target != COG:
            raise ValueError(f"{where}: {entry['type']} needs an oriented target; only {COG!r} is")


def _depth(pose_bone) -> int:
    depth = 0
    while pose_bone.parent is not None:
        pose_bone, depth = pose_bone.parent, depth + 1
    return depth


def constraint_retarget(
    session: RigSession,
    positions: np.ndarray,
    cog: np.ndarray,
    cog_rotation: np.ndarray,
    mapping: list[dict],
) -> np.ndarray:
    """Control vectors ``(N, C)`` whose mapped controls follow the targets; others default."""
    _check_mapping(session, mapping)
    rig = session.rig
    defaults = np.array([c["default"] for c in session.controls])
    session.apply(defaults)
    scale = session.length_scale
    joint_index = {name: i for i, name in enumerate(session.joint_names)}
    offsets = [_rest_offset(session, entry) for entry in mapping]
    empties = []
    try:
        for i, entry in enumerate(mapping):
            empty = bpy.data.objects.new(f"{TAG}_{i}_{entry['target']}", None)
            session.scene.collection.objects.link(empty)
            empties.append(empty)
            constraint = rig.pose.bones[entry["bone"]].constraints.new(entry["type"])
            constraint.name = TAG
            constraint.target = empty
        bones = sorted(
            {entry["bone"] for entry in mapping}, key=lambda b: _depth(rig.pose.bones[b])
        )
        columns = _bone_columns(session, bones)
        out = np.tile(defaults, (len(positions), 1))
        previous = {}
        for row in range(len(positions)):
            for entry, empty, offset in zip(mapping, empties, offsets, strict=True):
                if entry["target"] == COG:
                    rotation = session.to_rigmap.T @ np.asarray(cog_rotation[row])
                    matrix = Matrix(rotation.tolist()).to_4x4()
                    matrix.translation = Vector(session.to_blender_world(cog[row]))
                else:
                    target = cog[row] + positions[row, joint_index[entry["target"]]]
                    matrix = Matrix.Translation(Vector(session.to_blender_world(target) + offset))
                empty.matrix_world = matrix
            session.update()
            for bone in bones:
                pose_bone = rig.pose.bones[bone]
                local = rig.convert_space(
                    pose_bone=pose_bone,
                    matrix=pose_bone.matrix,
                    from_space="POSE",
                    to_space="LOCAL",
                )
                location, rotation, size = local.decompose()
                euler = rotation.to_euler(pose_bone.rotation_mode, *previous.get(bone, ()))
                previous[bone] = (euler,)
                channels = {"location": location * scale, "rotation_euler": euler, "scale": size}
                for column, attribute, axis in columns[bone]:
                    out[row, column] = channels[attribute][axis]
        return out
    finally:
        for entry in mapping:
            constraints = rig.pose.bones[entry["bone"]].constraints
            for constraint in [c for c in constraints if c.name.startswith(TAG)]:
                constraints.remove(constraint)
        for empty in empties:
            bpy.data.objects.remove(empty)
        session.apply(defaults)


def _rest_offset(session: RigSession, entry: dict) -> np.ndarray:
    """World offset (Blender units) from the target joint to the control at the default pose.

    Used when the entry says ``offset: true`` — the "maintain offset" of a TD's
    script, for controls that do not sit on a joint (a wolf's foot IK at the
    ground). The rig is at its defaults when this is called.
    """
    if not entry.get("offset") or entry["target"] == COG:
        return np.zeros(3)
    rig = session.rig
    world = rig.matrix_world
    control = world @ rig.pose.bones[entry["bone"]].head
    joint = world @ rig.pose.bones[entry["target"]].head
    return np.array(control - joint)


def _bone_columns(session: RigSession, bones: list[str]) -> dict[str, list]:
    wanted = set(bones)
    columns: dict[str, list] = {bone: [] for bone in bones}
    for column, control in enumerate(session.controls):
        if control["bone"] in wanted and "attribute" in control:
            columns[control["bone"]].append((column, control["attribute"], control["axis"]))
    return columns
