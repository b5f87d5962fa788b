"""A user's actions read back as keys on the rig's controls, and the checks before a long run.

Runs inside Blender (imports bpy). The main process (:mod:`rigmap.animation.blend_corpus`)
turns what :func:`read_file` reports into rigmap clips and a corpus.

For every action (or those whose name matches a glob) the F-curves that address the
armature's pose bones are reported with their keys exactly as stored — frame, value,
interpolation, both handles — and with Blender's own evaluation of the curve at every
whole frame of the action's frame range (the reference the import is checked against).
Values are in Blender's units here (metres, radians); the main process converts.

Curves rigmap's keyframe model cannot carry key for key are *baked* (one linear key a
frame, from Blender's evaluation): easing interpolations (sine, elastic, ...), F-curve
modifiers (cycles, noise, ...), linear extrapolation, and quaternion / axis-angle rotations
(the rig's controls are Euler angles: the rotation is converted frame by frame).
"""

from __future__ import annotations

import math
import re
from fnmatch import fnmatchcase

import bpy
from mathutils import Quaternion
from rig_session import AXES, TRANSFORM_CHANNELS, RigSession, SessionError, open_blend

#: interpolations rigmap's keyframe model evaluates itself (the others are baked)
MODELLED = {"BEZIER": "bezier", "LINEAR": "linear", "CONSTANT": "constant"}
#: constraint types whose result depends on the scene frame, not on the controls
FRAME_CONSTRAINTS = {
    "FOLLOW_PATH": "follows a path along its animated evaluation time",
    "CAMERA_SOLVER": "plays a motion-tracking camera solve",
    "FOLLOW_TRACK": "follows a motion-tracking track",
    "OBJECT_SOLVER": "plays a motion-tracking object solve",
    "TRANSFORM_CACHE": "plays a transform cache (Alembic/USD)",
}
_BONE_PATH = re.compile(r'^pose\.bones\["((?:[^"\\]|\\.)*)"\]')
_CHANNEL = re.compile(
    r"^\.(location|rotation_euler|scale|rotation_quaternion|rotation_axis_angle)$"
)
_PROPERTY = re.compile(r'^\["((?:[^"\\]|\\.)*)"\]$')
_FRAME_WORD = re.compile(r"\bframe\b")


class BlendFileError(ValueError):
    """The file does not hold what the import needs; the message names file, armature, action."""


def resolve_armature(path: str, armature: str | None, use_scripts: bool) -> str:
    """The armature to use: the named one, else the only one in the file."""
    open_blend(path, use_scripts)
    names = sorted(o.name for o in bpy.data.objects if o.type == "ARMATURE")
    if armature is not None:
        return armature  # RigSession says if it is missing, listing the armatures
    if not names:
        raise BlendFileError(f"{path}: the file has no armature object; nothing to import")
    if len(names) > 1:
        raise BlendFileError(
            f"{path}: the file has {len(names)} armature objects {names}; choose one with "
            "rig.armature=NAME"
        )
    return names[0]


def default_cog_bone(path: str, armature: str) -> str:
    """``torso`` if the armature has one (Rigify), else its first bone without a parent."""
    obj = bpy.data.objects.get(armature)
    if obj is None or obj.type != "ARMATURE":
        return "torso"  # RigSession reports the missing armature
    bones = obj.data.bones
    if "torso" in bones:
        return "torso"
    roots = [b.name for b in bones if b.parent is None]
    if not roots:
        raise BlendFileError(f"{path}: armature {armature!r} has no bones")
    return roots[0]


def open_session(options: dict) -> RigSession:
    options = dict(options)
    options["armature"] = resolve_armature(
        options["path"], options.get("armature"), bool(options.get("use_scripts", False))
    )
    if not options.get("cog_bone"):
        options["cog_bone"] = default_cog_bone(options["path"], options["armature"])
    # every bone stays (a keyed control may move no chosen joint), keys stay in the file
    options.update(prune=False, keep_animation=True)
    return RigSession(options)


# --- actions --------------------------------------------------------------------
def _slot_for(action, rig):
    """The action's slot that animates ``rig``: the assigned one, the rig's, or the only one."""
    slots = [s for s in action.slots if s.target_id_type in ("OBJECT", "UNSPECIFIED")]
    animation = rig.animation_data
    if animation is not None and animation.action == action and animation.action_slot:
        return animation.action_slot
    for slot in slots:
        if slot.identifier == "OB" + rig.name:
            return slot
    # an action nobody uses (kept by a fake user) with one slot; a slot that animates
    # other objects is theirs
    free = [s for s in slots if not [u for u in s.users() if u != rig]]
    if len(slots) == 1 and free:
        return slots[0]
    return None


def _fcurves(action, slot):
    from bpy_extras import anim_utils

    bag = anim_utils.action_get_channelbag_for_slot(action, slot)
    return list(bag.fcurves) if bag is not None else []


def _parse(data_path: str):
    """``(bone, channel attribute or None, property or None)`` of a pose-bone data path."""
    match = _BONE_PATH.match(data_path)
    if match is None:
        return None
    bone = bpy.utils.unescape_identifier(match.group(1))
    rest = data_path[match.end() :]
    channel = _CHANNEL.match(rest)
    if channel:
        return bone, channel.group(1), None
    prop = _PROPERTY.match(rest)
    if prop:
        return bone, None, bpy.utils.unescape_identifier(prop.group(1))
    return bone, None, None


def _frame_range(action) -> tuple[int, int]:
    start, end = action.frame_range  # the manual range if set, else the keys'
    return math.floor(start + 1e-6), math.ceil(end - 1e-6)


def _keys(fcurve) -> list[list]:
    return [
        [
            float(p.co[0]),
            float(p.co[1]),
            MODELLED.get(p.interpolation, p.interpolation),
            [float(p.handle_left[0]), float(p.handle_left[1])],
            [float(p.handle_right[0]), float(p.handle_right[1])],
        ]
        for p in fcurve.keyframe_points
    ]


def _bake_reason(fcurve) -> str | None:
    easing = sorted({p.interpolation for p in fcurve.keyframe_points} - set(MODELLED))
    if easing:
        return f"interpolation {easing}"
    active = [m.type for m in fcurve.modifiers if not m.mute]
    if active:
        return f"F-curve modifiers {active}"
    if fcurve.extrapolation != "CONSTANT" and len(fcurve.keyframe_points) > 1:
        return f"{fcurve.extrapolation.lower()} extrapolation"
    return None


def read_actions(session: RigSession, pattern: str) -> dict:
    """Every matching action's curves on the rig's controls (see the module docstring)."""
    rig, path = session.rig, session.options["path"]
    by_channel = {}
    for control in session.controls:
        key = (control["bone"], control.get("attribute"), control.get("axis", 0))
        if "property" in control:
            key = (control["bone"], None, control["property"])
        by_channel[key] = control
    deform = {b.name for b in rig.data.bones if b.use_deform}
    names = [a.name for a in bpy.data.actions if fnmatchcase(a.name, pattern)]
    actions, skipped = [], []
    for name in names:
        action = bpy.data.actions[name]
        slot = _slot_for(action, rig)
        if slot is None:
            skipped.append({"action": name, "why": "no slot for an armature object"})
            continue
        actions.append(_read_action(session, action, slot, by_channel, deform))
    scene = bpy.context.scene
    return {
        "path": path,
        "armature": rig.name,
        "cog_bone": session.options["cog_bone"],
        "fps": scene.render.fps / scene.render.fps_base,
        "all_actions": [a.name for a in bpy.data.actions],
        "actions": actions,
        "skipped": skipped,
        "limits": control_limits(session),
        "controls": session.controls,
        "deform_bones": sorted(deform),
        "joint_names": session.joint_names,
        "python_drivers": session.description()["stats"]["python_drivers"],
    }


def _read_action(session, action, slot, by_channel: dict, deform: set) -> dict:
    start, end = _frame_range(action)
    frames = list(range(start, end + 1))
    curves, ignored, quaternions = [], [], {}
    for fcurve in _fcurves(action, slot):
        if fcurve.mute or not len(fcurve.keyframe_points):
            continue
        parsed = _parse(fcurve.data_path)
        where = f"{fcurve.data_path}[{fcurve.array_index}]"
        if parsed is None:
            ignored.append({"curve": where, "why": "not a pose-bone channel"})
            continue
        bone, attribute, prop = parsed
        if attribute in ("rotation_quaternion", "rotation_axis_angle"):
            quaternions.setdefault((bone, attribute), {})[fcurve.array_index] = fcurve
            continue
        if attribute is not None:
            control = by_channel.get((bone, attribute, fcurve.array_index))
        elif prop is not None:
            control = by_channel.get((bone, None, prop))
        else:
            control = None
        if control is None:
            why = "deform bone" if bone in deform else "not a control of the rig"
            ignored.append({"curve": where, "bone": bone, "why": why})
            continue
        curves.append(
            {
                "control": control["name"],
                "keys": _keys(fcurve),
                "bake": _bake_reason(fcurve),
                "samples": [float(fcurve.evaluate(f)) for f in frames],
            }
        )
    for (bone, attribute), parts in quaternions.items():
        baked = _bake_rotation(session, bone, attribute, parts, frames, by_channel)
        if baked is None:
            why = "deform bone" if bone in deform else "not a control of the rig"
            ignored.append({"curve": f'pose.bones["{bone}"].{attribute}', "bone": bone, "why": why})
        curves.extend(baked or [])
    return {"name": action.name, "start": start, "end": end, "curves": curves, "ignored": ignored}


def _bake_rotation(session, bone, attribute, parts, frames, by_channel):
    """A quaternion / axis-angle curve set as per-frame Euler keys on the bone's controls."""
    pose_bone = session.rig.pose.bones.get(bone)
    if pose_bone is None or not any((bone, "rotation_euler", i) in by_channel for i in range(3)):
        return None
    order = pose_bone.rotation_mode if pose_bone.rotation_mode in _EULER_ORDERS else "XYZ"
    rest = [1.0, 0.0, 0.0, 0.0] if attribute == "rotation_quaternion" else [0.0, 0.0, 1.0, 0.0]
    eulers, previous = [], None
    for f in frames:
        v = [float(parts[i].evaluate(f)) if i in parts else rest[i] for i in range(4)]
        if attribute == "rotation_quaternion":
            q = Quaternion(v).normalized()
        else:
            q = Quaternion(v[1:], v[0])
        e = q.to_euler(order) if previous is None else q.to_euler(order, previous)
        eulers.append([e[0], e[1], e[2]])
        previous = e
    curves = []
    for i in range(3):
        control = by_channel.get((bone, "rotation_euler", i))
        if control is None:
            continue
        samples = [float(e[i]) for e in eulers]
        keys = [
            [float(f), s, "linear", [float(f), s], [float(f), s]]
            for f, s in zip(frames, samples, strict=True)
        ]
        curves.append(
            {
                "control": control["name"],
                "keys": keys,
                "bake": f"{attribute} keys (Euler {order} controls)",
                "samples": samples,
                "baked_keys": True,
            }
        )
    return curves


_EULER_ORDERS = {"XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"}


def control_limits(session: RigSession) -> dict:
    """Control name -> ``[lower, upper]`` (control units) from the bones' local-space limit
    constraints and the custom properties' hard ranges."""
    limits = {}
    scale = session.length_scale
    for control in session.controls:
        if "property" in control:
            low, high = control.get("hard_min"), control.get("hard_max")
            if low is not None or high is not None:
                limits[control["name"]] = [low, high]
            continue
        pose_bone = session.rig.pose.bones[control["bone"]]
        axis = AXES[control["axis"]]
        factor = scale if control["kind"] == "translate" else 1.0
        wanted = {
            "location": "LIMIT_LOCATION",
            "rotation_euler": "LIMIT_ROTATION",
            "scale": "LIMIT_SCALE",
        }[control["attribute"]]
        for constraint in pose_bone.constraints:
            if constraint.type != wanted or constraint.mute or constraint.owner_space != "LOCAL":
                continue
            if wanted == "LIMIT_ROTATION":
                if getattr(constraint, f"use_limit_{axis}"):
                    low = getattr(constraint, f"min_{axis}")
                    high = getattr(constraint, f"max_{axis}")
                    limits[control["name"]] = [low, high]
            else:
                low = getattr(constraint, f"min_{axis}") * factor
                high = getattr(constraint, f"max_{axis}") * factor
                use_low = getattr(constraint, f"use_min_{axis}")
                use_high = getattr(constraint, f"use_max_{axis}")
                if use_low or use_high:
                    limits[control["name"]] = [low if use_low else None, high if use_high else None]
    return limits


# --- checks ---------------------------------------------------------------------
def _animated(id_block) -> str | None:
    data = getattr(id_block, "animation_data", None)
    if data is None:
        return None
    if data.action is not None:
        return f"action {data.action.name!r}"
    if data.use_nla and any(track.strips for track in data.nla_tracks):
        return "NLA strips"
    if len(data.drivers):
        return "drivers"
    return None


def frame_dependence(session: RigSession) -> list[str]:
    """Drivers and constraints that make the rig's pose depend on the frame number."""
    rig, path = session.rig, session.options["path"]
    found = []
    for owner in (rig, rig.data):
        data = owner.animation_data
        if data is None:
            continue
        for fcurve in data.drivers:
            if fcurve.mute:
                continue
            driver = fcurve.driver
            where = f"driver on {fcurve.data_path}[{fcurve.array_index}] of armature {rig.name!r}"
            if driver.type == "SCRIPTED" and _FRAME_WORD.search(driver.expression):
                found.append(
                    f"{path}: {where} reads the frame number (expression {driver.expression!r})"
                )
                continue
            for variable in driver.variables:
                for target in variable.targets:
                    reads = (target.data_path or "").split(".")[-1]
                    if target.id_type == "SCENE" and reads.startswith("frame"):
                        found.append(
                            f"{path}: {where} reads the scene's {reads} (variable "
                            f"{variable.name!r})"
                        )
    owners = [(f"object {rig.name!r}", rig.constraints)]
    owners += [(f"bone {b.name!r}", b.constraints) for b in rig.pose.bones]
    for owner, constraints in owners:
        for constraint in constraints:
            if constraint.mute or constraint.influence == 0.0:
                continue
            label = f"{path}: constraint {constraint.name!r} ({constraint.type}) on {owner}"
            if constraint.type in FRAME_CONSTRAINTS:
                found.append(f"{label} {FRAME_CONSTRAINTS[constraint.type]}")
                continue
            target = getattr(constraint, "target", None)
            if target is not None and target != rig:
                how = _animated(target)
                if how is not None:
                    found.append(
                        f"{label} follows object {target.name!r}, which is animated "
                        f"({how}): the pose depends on the frame"
                    )
    return found


# --- writing (the test fixture: a user's file with keyed actions) ----------------------
def write_actions(
    session: RigSession, clips: list[dict], fps: float | None, scene_range: bool = False
) -> dict:
    """Key each clip as an action of its own (fake user, manual frame range) on the rig.

    ``clips``: ``{"name", "start", "end", "curves": {control: [[frame, value, interpolation,
    in_handle or None, out_handle or None], ...]}}`` in control units (cm, radians), and
    optionally ``"handle_type"`` for the given handles (``FREE`` unless said; a mapping's
    keys are ``ALIGNED``, so an edited handle keeps the curve smooth). Keys
    without handles get Blender's auto-clamped handles, as keys an animator sets. The last
    clip stays assigned to the rig; the action the rig had before (a user's file opened
    with its animation) gets a fake user, so the saved copy still holds it. ``scene_range``
    sets the scene's frame range to the last clip's.
    """
    from keyframes import data_path

    rig = session.rig
    by_name = {c["name"]: c for c in session.controls}
    animation = rig.animation_data_create()
    if animation.action is not None:
        animation.action.use_fake_user = True
    keys = 0
    for clip in clips:
        given = clip.get("handle_type", "FREE")
        action = bpy.data.actions.new(clip["name"])
        action.use_fake_user = True  # kept in the file when no object uses it
        animation.action = action
        for name, clip_keys in clip["curves"].items():
            control = by_name[name]
            path, index = data_path(control)
            fcurve = action.fcurve_ensure_for_datablock(
                rig, path, index=index, group_name=control["bone"]
            )
            scale = 1.0 / session.length_scale if control["kind"] == "translate" else 1.0
            points = fcurve.keyframe_points
            points.add(len(clip_keys))
            for point, (frame, value, interpolation, left, right) in zip(
                points, clip_keys, strict=True
            ):
                point.co = (frame, value * scale)
                point.interpolation = interpolation.upper()
                for side, handle in (("left", left), ("right", right)):
                    if handle is None:
                        setattr(point, f"handle_{side}_type", "AUTO_CLAMPED")
                    else:
                        setattr(point, f"handle_{side}_type", given)
                        setattr(point, f"handle_{side}", (handle[0], handle[1] * scale))
            fcurve.update()
            keys += len(clip_keys)
        action.use_frame_range = True
        action.frame_start, action.frame_end = clip["start"], clip["end"]
    scene = bpy.context.scene
    if fps is not None:
        scene.render.fps = max(1, round(fps))
        scene.render.fps_base = scene.render.fps / fps
    if scene_range and clips:
        scene.frame_start, scene.frame_end = clips[-1]["start"], clips[-1]["end"]
    return {"actions": len(clips), "keys": keys, "file_actions": len(bpy.data.actions)}


__all__ = [
    "TRANSFORM_CHANNELS",
    "BlendFileError",
    "SessionError",
    "frame_dependence",
    "open_session",
    "read_actions",
    "write_actions",
]
