"""Control curves as keyframes on the rig, and reading keyed files back.

Runs inside Blender. Keys go on the control bones' own channels (the ones an
animator grabs), one F-curve per control, grouped by bone, so the file opens
as ordinary editable animation on the Rigify rig.
"""

from __future__ import annotations

import os

import bpy
import numpy as np
from rig_session import RigSession


def data_path(control: dict) -> tuple[str, int]:
    bone = bpy.utils.escape_identifier(control["bone"])
    if "attribute" in control:
        return f'pose.bones["{bone}"].{control["attribute"]}', control["axis"]
    key = bpy.utils.escape_identifier(control["property"])
    return f'pose.bones["{bone}"]["{key}"]', 0


def write_keyframes(
    session: RigSession,
    frames: np.ndarray,
    values: np.ndarray,
    names: list[str],
    action: str,
    fps: float | None = None,
) -> dict:
    """Key ``values[:, k]`` on control ``names[k]`` at ``frames`` (control units).

    ``fps`` (frames per second) sets the scene's playback rate; ``None`` keeps the file's.
    """
    by_name = {c["name"]: c for c in session.controls}
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise ValueError(f"rig {session.rig.name!r} has no controls {unknown[:10]}")
    rig = session.rig
    animation = rig.animation_data_create()
    animation.action = bpy.data.actions.new(action)
    order = np.argsort(frames, kind="stable")
    frames = np.asarray(frames, dtype=np.float64)[order]
    values = np.asarray(values, dtype=np.float64)[order]
    for column, name in enumerate(names):
        control = by_name[name]
        path, index = data_path(control)
        fcurve = animation.action.fcurve_ensure_for_datablock(
            rig, path, index=index, group_name=control["bone"]
        )
        scale = 1.0 / session.length_scale if control["kind"] == "translate" else 1.0
        points = fcurve.keyframe_points
        points.add(len(frames))
        co = np.column_stack([frames, values[:, column] * scale]).astype(np.float32)
        points.foreach_set("co", co.ravel())
        if control.get("value_type") in ("int", "bool"):
            for point in points:
                point.interpolation = "CONSTANT"
        fcurve.update()
    scene = bpy.context.scene
    if fps is not None:  # Blender's rate is an integer over a base: 29.97 = 30 / 1.001
        scene.render.fps = max(1, round(fps))
        scene.render.fps_base = scene.render.fps / fps
    scene.frame_start = int(np.floor(frames.min()))
    scene.frame_end = int(np.ceil(frames.max()))
    scene.frame_set(scene.frame_start)
    return {"fcurves": len(names), "keys": len(frames) * len(names)}


def save_blend(out_path: str) -> None:
    """Save the open file to ``out_path`` atomically (temp file in the folder, then rename)."""
    out_path = os.path.abspath(out_path)
    folder = os.path.dirname(out_path)
    os.makedirs(folder, exist_ok=True)
    temp = os.path.join(folder, f".{os.path.basename(out_path)}.{os.getpid()}.tmp.blend")
    try:
        bpy.ops.wm.save_as_mainfile(filepath=temp, compress=True, check_existing=False)
        os.replace(temp, out_path)
    finally:
        for leftover in (temp, temp + "1"):
            if os.path.exists(leftover):
                os.remove(leftover)


def play(session: RigSession, frames: np.ndarray) -> dict:
    """For each frame: the keyed control values and the pose they produce."""
    scene = bpy.context.scene
    n = len(frames)
    controls = np.empty((n, len(session.controls)))
    positions = np.empty((n, len(session.joint_names), 3))
    cog = np.empty((n, 3))
    cog_rotation = np.empty((n, 3, 3))
    for row, frame in enumerate(np.asarray(frames, dtype=np.float64)):
        whole = int(np.floor(frame))
        scene.frame_set(whole, subframe=float(frame - whole))
        controls[row] = session.read_controls()
        positions[row], cog[row], cog_rotation[row] = session.read_pose()
    return {"controls": controls, "positions": positions, "cog": cog, "cog_rotation": cog_rotation}
