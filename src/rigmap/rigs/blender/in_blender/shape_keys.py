"""A mesh with one shape key per control and an action keying their weights, and back.

Runs inside Blender (imports bpy). The main process (:mod:`rigmap.rigs.blender.shape_keys`)
sends Blender-ready numbers: vertices in metres in Blender's Z-up axes, the weights
already divided out; nothing here converts units.

The scene starts empty (factory settings, no objects): a worker may hold a rig session
from an earlier request, and the file must hold only the face.
"""

from __future__ import annotations

import bpy
import numpy as np

BASIS_NAME = "Basis"


def new_empty_scene() -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)


def build_mesh_object(name: str, vertices: np.ndarray, triangles: np.ndarray):
    """A mesh object at the origin from ``(V, 3)`` vertices and ``(F, 3)`` vertex indices."""
    mesh = bpy.data.meshes.new(name)
    n_vertices, n_triangles = len(vertices), len(triangles)
    mesh.vertices.add(n_vertices)
    mesh.vertices.foreach_set("co", np.asarray(vertices, dtype=np.float32).ravel())
    mesh.loops.add(3 * n_triangles)
    mesh.loops.foreach_set("vertex_index", np.asarray(triangles, dtype=np.int32).ravel())
    mesh.polygons.add(n_triangles)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * n_triangles, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.shade_smooth()  # the face is a smooth surface; flat shading shows its triangles
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def key_value_path(name: str) -> str:
    return f'key_blocks["{bpy.utils.escape_identifier(name)}"].value'


def write_shape_keys(
    object_name: str,
    rest: np.ndarray,
    triangles: np.ndarray,
    shapes: np.ndarray,
    names: list[str],
    frames: np.ndarray,
    weights: np.ndarray,
    action_name: str,
    fps: float,
) -> dict:
    """A new scene holding the mesh with ``shapes[k]`` as shape key ``names[k]``, keyed to
    ``weights[:, k]`` at ``frames`` (one linear F-curve per key) by a new action.

    Keys are linear: a synthesised table is a sampled curve, and straight lines between
    samples invent no motion and keep every weight Blender evaluates inside the keyed
    range (so inside the sliders, which clamp).
    """
    new_empty_scene()
    obj = build_mesh_object(object_name, rest, triangles)
    obj.shape_key_add(name=BASIS_NAME, from_mix=False)
    key = obj.data.shape_keys
    key.use_relative = True
    order = np.argsort(frames, kind="stable")
    frames = np.asarray(frames, dtype=np.float64)[order]
    weights = np.asarray(weights, dtype=np.float64)[order]
    animation = key.animation_data_create()
    animation.action = bpy.data.actions.new(action_name)
    for column, name in enumerate(names):
        block = obj.shape_key_add(name=name, from_mix=False)
        block.data.foreach_set("co", np.asarray(shapes[column], dtype=np.float32).ravel())
        # the slider range is also the value's hard limit: widen it to hold every weight
        block.slider_max = max(1.0, float(weights[:, column].max()))
        block.slider_min = min(0.0, float(weights[:, column].min()))
        fcurve = animation.action.fcurve_ensure_for_datablock(key, key_value_path(name))
        points = fcurve.keyframe_points
        points.add(len(frames))
        co = np.column_stack([frames, weights[:, column]]).astype(np.float32)
        points.foreach_set("co", co.ravel())
        for point in points:
            point.interpolation = "LINEAR"
        fcurve.update()
    scene = bpy.context.scene
    scene.render.fps = max(1, round(fps))  # Blender's rate is an integer over a base
    scene.render.fps_base = scene.render.fps / fps
    scene.frame_start = int(np.floor(frames.min()))
    scene.frame_end = int(np.ceil(frames.max()))
    scene.frame_set(scene.frame_start)
    return {
        "object": obj.name,
        "action": animation.action.name,
        "shape_keys": len(names),
        "keys": len(frames) * len(names),
    }


def shape_key_object(path: str):
    """The file's only mesh object with shape keys (an error names the file and the choice)."""
    candidates = sorted(
        (o for o in bpy.data.objects if o.type == "MESH" and o.data.shape_keys is not None),
        key=lambda o: o.name,
    )
    if len(candidates) != 1:
        names = [o.name for o in candidates]
        raise ValueError(
            f"{path}: expected one mesh object with shape keys, found {len(names)} {names[:10]}"
        )
    return candidates[0]


def read_shape_keys(path: str, vertices_at: float | None = None) -> tuple[dict, dict]:
    """Every shape key's weight at each whole frame of the scene range, as Blender plays
    it; with ``vertices_at``, also the evaluated world vertices (metres) at that frame."""
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False, use_scripts=False)
    obj = shape_key_object(path)
    key = obj.data.shape_keys
    blocks = [b for b in key.key_blocks if b != key.reference_key]
    scene = bpy.context.scene
    frames = np.arange(scene.frame_start, scene.frame_end + 1, dtype=np.float64)
    weights = np.empty((len(frames), len(blocks)))
    for row, frame in enumerate(frames):
        scene.frame_set(int(frame))
        weights[row] = [b.value for b in blocks]
    arrays = {"frames": frames, "weights": weights}
    if vertices_at is not None:
        arrays["vertices"] = evaluated_vertices(obj, float(vertices_at))
    info = {
        "object": obj.name,
        "names": [b.name for b in blocks],
        "fps": scene.render.fps / scene.render.fps_base,
    }
    return info, arrays


def evaluated_vertices(obj, frame: float) -> np.ndarray:
    """The object's vertices after shape keys (and any modifier) at ``frame``, in world space."""
    scene = bpy.context.scene
    whole = int(np.floor(frame))
    scene.frame_set(whole, subframe=frame - whole)
    from evaluated_mesh import evaluated_world_vertices

    return evaluated_world_vertices(obj)
