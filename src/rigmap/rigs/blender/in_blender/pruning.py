"""Drop the bones that cannot move the joints we read, so each evaluation is cheaper.

A production rig evaluates hundreds of bones it does not need for one question:
the Rigify human's face is ~300 of its ~700 bones, and with face joints left out
of the selection none of them can change a body joint. A bone can only affect
another through a dependency Blender knows about — parenting, a constraint
target, an IK chain, a B-bone handle or a driver variable — so the bones
reachable from the selected joints through those edges are all that matter;
the rest are removed from this worker's in-memory copy (never from a file).
Controls on removed bones stay in the control table and simply do nothing,
which is exactly their effect on the selected joints.

Objects the armature does not read (the meshes it deforms, its bone-shape
widgets, a metarig) are removed too: each costs the depsgraph time per update.
"""

from __future__ import annotations

import re

import bpy

_POSE_BONE_PATH = re.compile(r'pose\.bones\["((?:[^"\\]|\\.)*)"\]')
_DATA_BONE_PATH = re.compile(r'^bones\["((?:[^"\\]|\\.)*)"\]')


def _bone_in_path(path: str, pattern: re.Pattern) -> str | None:
    match = pattern.search(path)
    return match.group(1).replace('\\"', '"') if match else None


def bone_dependencies(rig) -> tuple[dict[str, set[str]], set[str]]:
    """For each bone, the bones its evaluation reads; plus bones read by object-level drivers."""
    bones = rig.pose.bones
    deps: dict[str, set[str]] = {b.name: set() for b in bones}
    always: set[str] = set()
    for pose_bone in bones:
        needs = deps[pose_bone.name]
        if pose_bone.parent is not None:
            needs.add(pose_bone.parent.name)
        bone = pose_bone.bone
        for handle in (bone.bbone_custom_handle_start, bone.bbone_custom_handle_end):
            if handle is not None:
                needs.add(handle.name)
        for constraint in pose_bone.constraints:
            needs |= _constraint_targets(constraint, rig)
            if constraint.type in ("IK", "SPLINE_IK"):
                # The solver moves the whole chain above the constrained bone.
                for member in _chain(pose_bone, getattr(constraint, "chain_count", 0)):
                    deps[member.name].add(pose_bone.name)
    for owner, pattern in ((rig, _POSE_BONE_PATH), (rig.data, _DATA_BONE_PATH)):
        if owner.animation_data is None:
            continue
        for fcurve in owner.animation_data.drivers:
            read = _driver_bones(fcurve.driver, rig)
            driven = _bone_in_path(fcurve.data_path, pattern)
            if driven in deps:
                deps[driven] |= read
            else:
                always |= read
    return deps, always


def _constraint_targets(constraint, rig) -> set[str]:
    found = set()
    if getattr(constraint, "target", None) == rig and getattr(constraint, "subtarget", ""):
        found.add(constraint.subtarget)
    if getattr(constraint, "pole_target", None) == rig and getattr(
        constraint, "pole_subtarget", ""
    ):
        found.add(constraint.pole_subtarget)
    for target in getattr(constraint, "targets", ()):  # Armature constraint
        if target.target == rig and target.subtarget:
            found.add(target.subtarget)
    return found


def _chain(pose_bone, count: int) -> list:
    chain, bone = [], pose_bone
    while bone is not None and (count == 0 or len(chain) < count):
        chain.append(bone)
        bone = bone.parent
    return chain


def _driver_bones(driver, rig) -> set[str]:
    found = set()
    for variable in driver.variables:
        for target in variable.targets:
            if target.id not in (rig, rig.data):
                continue
            if variable.type == "SINGLE_PROP":
                name = _bone_in_path(target.data_path, _POSE_BONE_PATH) or _bone_in_path(
                    target.data_path, _DATA_BONE_PATH
                )
                if name:
                    found.add(name)
            elif target.bone_target:
                found.add(target.bone_target)
    return found


def needed_bones(rig, seeds: set[str]) -> set[str]:
    """Every bone the ``seeds`` depend on, transitively (the seeds included)."""
    deps, always = bone_dependencies(rig)
    needed: set[str] = set()
    stack = [b for b in seeds | always if b in deps]
    while stack:
        name = stack.pop()
        if name in needed:
            continue
        needed.add(name)
        stack.extend(d for d in deps[name] if d in deps and d not in needed)
    return needed


def prune_to(rig, seeds: set[str], view_layer) -> int:
    """Remove the bones (and downstream objects) the ``seeds`` do not need; return how many."""
    _remove_unrelated_objects(rig)
    keep = needed_bones(rig, seeds)
    drop = [b.name for b in rig.data.bones if b.name not in keep]
    if not drop:
        return 0
    _remove_drivers_on(rig, set(drop))
    view_layer.objects.active = rig
    rig.hide_set(False)
    rig.hide_viewport = False
    bpy.ops.object.mode_set(mode="EDIT")
    edit_bones = rig.data.edit_bones
    for name in drop:
        edit_bones.remove(edit_bones[name])
    bpy.ops.object.mode_set(mode="OBJECT")
    view_layer.update()
    return len(drop)


def _remove_drivers_on(rig, dropped: set[str]) -> None:
    for owner, pattern in ((rig, _POSE_BONE_PATH), (rig.data, _DATA_BONE_PATH)):
        if owner.animation_data is None:
            continue
        drivers = owner.animation_data.drivers
        for fcurve in [f for f in drivers if _bone_in_path(f.data_path, pattern) in dropped]:
            drivers.remove(fcurve)


def _objects_read_by(obj) -> set:
    """Objects whose state ``obj``'s evaluation reads: parent, constraint and driver targets."""
    read = {obj.parent}
    stacks = [obj.constraints]
    if obj.type == "ARMATURE" and obj.pose is not None:
        stacks += [pose_bone.constraints for pose_bone in obj.pose.bones]
    for constraints in stacks:
        for constraint in constraints:
            read.add(getattr(constraint, "target", None))
            read.add(getattr(constraint, "pole_target", None))
            read.update(t.target for t in getattr(constraint, "targets", ()))
    for owner in (obj, obj.data):
        animation = getattr(owner, "animation_data", None)
        if animation is not None:
            for fcurve in animation.drivers:
                for variable in fcurve.driver.variables:
                    read.update(t.id for t in variable.targets)
    return {o for o in read if isinstance(o, bpy.types.Object)}


def _remove_unrelated_objects(rig) -> None:
    """Remove every object the armature's evaluation does not read (widgets, meshes, metarig).

    Each object in the scene costs the depsgraph time on every update, even when it
    does not change: the Rigify human's ~220 bone-shape widgets add ~45% per pose.
    """
    keep, stack = {rig}, [rig]
    while stack:
        for needed in _objects_read_by(stack.pop()):
            if needed not in keep:
                keep.add(needed)
                stack.append(needed)
    for obj in [o for o in bpy.data.objects if o not in keep]:
        bpy.data.objects.remove(obj)
