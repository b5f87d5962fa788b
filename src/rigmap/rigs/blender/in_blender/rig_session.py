"""One armature opened inside Blender: its controls, its joints, and evaluating it.

Runs inside Blender's Python (imports bpy). The main process never imports it.

Units at the boundary: lengths in the rig's length unit times ``length_scale``
(Blender metres x 100 = centimetres for the built-in rigs), rotations in radians
as Euler angles. Positions are given in rigmap's axes (``up_axis="Y"``, the
default): Y up, the character facing +Z, +X its left — Blender's Z-up world with
the character facing -Y, turned -90 degrees about X; ``up_axis="Z"`` keeps
Blender's axes. Control bones that rotate by quaternion or axis-angle are
switched to an Euler mode (``euler_order``) when the file is opened, so every
rotation channel is one angle an animator can key; the Rigify rigs are cached
already converted.
"""

from __future__ import annotations

import math
from fnmatch import fnmatchcase

import bpy
import numpy as np
import pruning

AXES = "xyz"
TRANSFORM_CHANNELS = (
    ("location", "t", "translate"),
    ("rotation_euler", "r", "rotate"),
    ("scale", "s", "scale"),
)
LOCKS = {"location": "lock_location", "rotation_euler": "lock_rotation", "scale": "lock_scale"}

DEFAULT_OPTIONS = {
    "armature": "rig",
    "control_bones": ["*"],
    "exclude_bones": ["DEF-*", "MCH-*", "ORG-*", "VIS_*"],
    "joints": {"include": ["*"], "exclude": []},
    "cog_bone": "torso",
    "euler_order": "XYZ",
    "length_scale": 100.0,
    "up_axis": "Y",
    "translate_range": 30.0,
    "scale_range": [0.25, 3.0],
    "prune": True,
    "keep_animation": False,
    "use_scripts": False,
}


# Blender world -> rigmap axes, per ``up_axis`` option (rotations: det = +1).
TO_RIGMAP_AXES = {
    "Y": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
    "Z": np.eye(3),
}


class SessionError(ValueError):
    """The file or the options do not describe an armature this session can use."""


def matches(name: str, include, exclude) -> bool:
    return any(fnmatchcase(name, p) for p in include) and not any(
        fnmatchcase(name, p) for p in exclude
    )


def open_blend(path: str, use_scripts: bool) -> None:
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False, use_scripts=use_scripts)


def find_armature(name: str):
    obj = bpy.data.objects.get(name)
    if obj is None or obj.type != "ARMATURE":
        armatures = sorted(o.name for o in bpy.data.objects if o.type == "ARMATURE")
        found = "not an armature" if obj is not None else "missing"
        raise SessionError(
            f"{bpy.data.filepath}: armature object {name!r} is {found}; "
            f"armature objects in the file: {armatures}"
        )
    return obj


def convert_to_euler(rig, bone_names, order: str) -> int:
    """Switch quaternion/axis-angle bones to Euler ``order`` (Blender converts the values)."""
    converted = 0
    for name in bone_names:
        pose_bone = rig.pose.bones[name]
        if pose_bone.rotation_mode in ("QUATERNION", "AXIS_ANGLE"):
            pose_bone.rotation_mode = order
            converted += 1
    return converted


class RigSession:
    """An armature ready to evaluate: controls in, deform-bone heads out."""

    def __init__(self, options: dict):
        self.options = {**DEFAULT_OPTIONS, **options}
        opts = self.options
        open_blend(opts["path"], opts["use_scripts"])
        self.rig = find_armature(opts["armature"])
        self.scene = bpy.context.scene
        self.view_layer = bpy.context.view_layer
        self.length_scale = float(opts["length_scale"])
        if opts["up_axis"] not in TO_RIGMAP_AXES:
            raise SessionError(
                f"up_axis must be one of {sorted(TO_RIGMAP_AXES)}, got {opts['up_axis']!r}"
            )
        self.to_rigmap = TO_RIGMAP_AXES[opts["up_axis"]]
        self.total_bones = len(self.rig.pose.bones)
        self.deform_bones = sum(1 for b in self.rig.data.bones if b.use_deform)
        if not opts["keep_animation"] and self.rig.animation_data is not None:
            # Keyframes (the action or NLA strips) would override the controls; drivers stay.
            self.rig.animation_data.action = None
            self.rig.animation_data.use_nla = False
        self.control_bones = [
            b.name
            for b in self.rig.pose.bones
            if matches(b.name, opts["control_bones"], opts["exclude_bones"])
        ]
        self.euler_converted = convert_to_euler(self.rig, self.control_bones, opts["euler_order"])
        self.controls = self._discover_controls()
        self.joint_names = self._select_joints()
        if opts["cog_bone"] not in self.rig.pose.bones:
            raise SessionError(
                f"{opts['path']}: COG bone {opts['cog_bone']!r} not in armature "
                f"{self.rig.name!r}; control bones include {self.control_bones[:12]}"
            )
        self.joint_parents = self._joint_parents()
        self.pruned = 0
        if opts["prune"]:
            self.pruned = pruning.prune_to(
                self.rig, set(self.joint_names) | {opts["cog_bone"]}, self.view_layer
            )
        self._bind()

    # --- discovery --------------------------------------------------------
    def _discover_controls(self) -> list[dict]:
        opts = self.options
        controls = []
        for name in self.control_bones:
            pose_bone = self.rig.pose.bones[name]
            group = self._group(pose_bone)
            for attr, prefix, kind in TRANSFORM_CHANNELS:
                locks = getattr(pose_bone, LOCKS[attr])
                values = getattr(pose_bone, attr)
                for axis in range(3):
                    if locks[axis]:
                        continue
                    value = float(values[axis])
                    if kind == "translate":
                        value *= self.length_scale
                        reach = float(opts["translate_range"])
                        lower, upper = value - reach, value + reach
                    elif kind == "rotate":
                        lower, upper = value - math.pi, value + math.pi
                    else:
                        lower = min(float(opts["scale_range"][0]), value)
                        upper = max(float(opts["scale_range"][1]), value)
                    controls.append(
                        {
                            "name": f"{name}.{prefix}{AXES[axis]}",
                            "kind": kind,
                            "default": value,
                            "lower": lower,
                            "upper": upper,
                            "group": group,
                            "bone": name,
                            "attribute": attr,
                            "axis": axis,
                        }
                    )
            controls.extend(self._property_controls(pose_bone, group))
        names = [c["name"] for c in controls]
        clashes = sorted({n for n in names if names.count(n) > 1})
        if clashes:
            raise SessionError(
                f"control names clash (a custom property named like a channel?): {clashes}"
            )
        return controls

    def _property_controls(self, pose_bone, group: str) -> list[dict]:
        found = []
        for key in pose_bone.keys():
            value = pose_bone[key]
            if key.startswith("_") or not isinstance(value, int | float):  # bool is an int
                continue
            ui = pose_bone.id_properties_ui(key).as_dict()
            value_type = "bool" if isinstance(value, bool) else type(value).__name__
            hard = (float(ui.get("min", -math.inf)), float(ui.get("max", math.inf)))
            if value_type == "bool":
                lower, upper = hard = (0.0, 1.0)
            elif value_type == "int" and ui.get("items"):
                lower, upper = hard = (0.0, float(len(ui["items"]) - 1))
            else:
                lower = float(ui.get("soft_min", hard[0]))
                upper = float(ui.get("soft_max", hard[1]))
                if not abs(lower) < 1e6 or not abs(upper) < 1e6:  # "unbounded": a usable window
                    lower, upper = value - 10.0, value + 10.0
            value = float(value)
            found.append(
                {
                    "name": f"{pose_bone.name}.{key}",
                    "kind": "scalar",
                    "default": value,
                    "lower": min(lower, value),
                    "upper": max(upper, value),
                    "group": group,
                    "bone": pose_bone.name,
                    "property": key,
                    "value_type": value_type,
                    # Keyframes are clamped to the hard range; evaluation clamps alike.
                    "hard_min": hard[0] if math.isfinite(hard[0]) else None,
                    "hard_max": hard[1] if math.isfinite(hard[1]) else None,
                }
            )
        return found

    @staticmethod
    def _group(pose_bone) -> str:
        collections = [c.name for c in pose_bone.bone.collections]
        return collections[0] if collections else "other"

    def _select_joints(self) -> list[str]:
        selection = self.options["joints"]
        include = selection.get("include", ["*"])
        exclude = selection.get("exclude", [])
        deform = [b.name for b in self.rig.data.bones if b.use_deform]
        joints = [n for n in deform if matches(n, include, exclude)]
        if not joints:
            raise SessionError(
                f"{self.options['path']}: joint selection include={include} exclude={exclude} "
                f"matched none of the {len(deform)} deform bones of {self.rig.name!r} "
                f"(first: {deform[:8]})"
            )
        return joints

    def _joint_parents(self) -> list[int]:
        """Each joint's nearest ancestor that is a joint (``-1`` for none).

        Rigify parents some deform bones (face, breast) to helper bones; a helper
        ``ORG-x``/``MCH-x`` stands for its deform twin ``DEF-x`` when that is a joint.
        """
        index = {name: i for i, name in enumerate(self.joint_names)}

        def as_joint(name: str) -> int | None:
            if name in index:
                return index[name]
            prefix, _, rest = name.partition("-")
            return index.get(f"DEF-{rest}") if prefix in ("ORG", "MCH") else None

        parents = []
        for own, name in enumerate(self.joint_names):
            bone, parent = self.rig.data.bones[name].parent, None
            while bone is not None and parent in (None, own):  # ORG-x of DEF-x is itself
                parent, bone = as_joint(bone.name), bone.parent
            parents.append(-1 if parent in (None, own) else parent)
        return parents

    def description(self) -> dict:
        rig = self.rig
        python_drivers = sum(
            1
            for owner in (rig, rig.data)
            if owner.animation_data
            for fc in owner.animation_data.drivers
            if fc.driver.type == "SCRIPTED" and not fc.driver.is_simple_expression
        )
        return {
            "armature": rig.name,
            "path": self.options["path"],
            "blender_version": bpy.app.version_string,
            "controls": self.controls,
            "joint_names": self.joint_names,
            "parents": self.joint_parents,
            "cog_bone": self.options["cog_bone"],
            "stats": {
                "bones": self.total_bones,
                "control_bones": len(self.control_bones),
                "control_bones_with_channels": len({c["bone"] for c in self.controls}),
                "transform_channels": sum(1 for c in self.controls if c["kind"] != "scalar"),
                "custom_properties": sum(1 for c in self.controls if c["kind"] == "scalar"),
                "deform_bones": self.deform_bones,
                "joints": len(self.joint_names),
                "euler_converted_bones": self.euler_converted,
                "pruned_bones": self.pruned,
                "evaluated_bones": len(rig.pose.bones),
                "python_drivers": python_drivers,
            },
        }

    # --- evaluation -------------------------------------------------------
    def _bind(self) -> None:
        """Index arrays from control columns into the flat per-bone channel buffers."""
        bones = self.rig.pose.bones
        n = len(bones)
        self._buffers = {}
        for attr, _, _ in TRANSFORM_CHANNELS:
            buffer = np.zeros(3 * n, dtype=np.float32)
            bones.foreach_get(attr, buffer)
            self._buffers[attr] = buffer
        self._slots = {attr: ([], [], []) for attr, _, _ in TRANSFORM_CHANNELS}
        self._props = []  # (column, pose bone, key, value type, hard limits)
        for column, control in enumerate(self.controls):
            bone_index = bones.find(control["bone"])
            if bone_index < 0:
                continue  # pruned: it cannot move any selected joint
            if "attribute" in control:
                columns, flat, factor = self._slots[control["attribute"]]
                columns.append(column)
                flat.append(3 * bone_index + control["axis"])
                factor.append(1.0 / self.length_scale if control["kind"] == "translate" else 1.0)
            else:
                limits = (
                    -math.inf if control["hard_min"] is None else control["hard_min"],
                    math.inf if control["hard_max"] is None else control["hard_max"],
                )
                self._props.append(
                    (column, bones[bone_index], control["property"], control["value_type"], limits)
                )
        self._slots = {
            attr: (np.array(c, dtype=np.int64), np.array(f, dtype=np.int64), np.array(s))
            for attr, (c, f, s) in self._slots.items()
            if c
        }
        self._prop_values = {column: None for column, *_ in self._props}
        self._heads = np.zeros(3 * n, dtype=np.float32)
        self._joint_index = np.array([bones.find(j) for j in self.joint_names], dtype=np.int64)
        self._cog = bones[self.options["cog_bone"]]

    def apply(self, y: np.ndarray) -> None:
        """Set every bound channel and property from one control vector (control units)."""
        bones = self.rig.pose.bones
        for attr, (columns, flat, factor) in self._slots.items():
            buffer = self._buffers[attr]
            buffer[flat] = y[columns] * factor
            bones.foreach_set(attr, buffer)
        for column, pose_bone, key, value_type, (low, high) in self._props:
            value = min(max(float(y[column]), low), high)
            if self._prop_values[column] == value:
                continue
            if value_type == "int":
                pose_bone[key] = round(value)
            elif value_type == "bool":
                pose_bone[key] = value >= 0.5
            else:
                pose_bone[key] = value
            self._prop_values[column] = value
        self.update()

    def update(self) -> None:
        # A transform tag: the object is copied to its evaluated version (so the new channel
        # and property values reach it) and the pose, downstream of the transform, is
        # evaluated again, drivers included. It skips the armature-data work of the
        # GEOMETRY tag Blender uses when a person edits a channel (~30% less per pose);
        # tests compare against playback through Blender's own animation system.
        self.rig.update_tag(refresh={"OBJECT"})
        self.view_layer.update()

    def read_pose(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """COG-relative joint positions (J, 3), COG position (3,), COG rotation (3, 3).

        In rigmap's axes and length unit (see the module docstring).
        """
        world = np.array(self.rig.matrix_world, dtype=np.float64)
        self.rig.pose.bones.foreach_get("head", self._heads)
        heads = self._heads.reshape(-1, 3)[self._joint_index].astype(np.float64)
        heads = heads @ world[:3, :3].T + world[:3, 3]
        cog = world @ np.array(self._cog.matrix, dtype=np.float64)
        rotation = cog[:3, :3] / np.linalg.norm(cog[:3, :3], axis=0, keepdims=True)
        position = cog[:3, 3]
        axes, scale = self.to_rigmap, self.length_scale
        return (heads - position) @ axes.T * scale, axes @ position * scale, axes @ rotation

    def to_blender_world(self, points: np.ndarray) -> np.ndarray:
        """rigmap positions (length unit, rigmap axes) to Blender world coordinates."""
        return np.asarray(points) @ self.to_rigmap / self.length_scale

    def evaluate(self, Y: np.ndarray) -> dict:
        n, n_joints = len(Y), len(self.joint_names)
        positions = np.empty((n, n_joints, 3))
        cog = np.empty((n, 3))
        cog_rotation = np.empty((n, 3, 3))
        for row in range(n):
            self.apply(Y[row])
            positions[row], cog[row], cog_rotation[row] = self.read_pose()
        return {"positions": positions, "cog": cog, "cog_rotation": cog_rotation}

    def read_controls(self) -> np.ndarray:
        """The current value of every control (control units); pruned controls read NaN."""
        bones = self.rig.pose.bones
        y = np.full(len(self.controls), np.nan)
        for attr, (columns, flat, factor) in self._slots.items():
            buffer = np.zeros(3 * len(bones), dtype=np.float32)
            bones.foreach_get(attr, buffer)
            y[columns] = buffer[flat] / factor
        for column, pose_bone, key, *_ in self._props:
            y[column] = float(pose_bone[key])
        return y
