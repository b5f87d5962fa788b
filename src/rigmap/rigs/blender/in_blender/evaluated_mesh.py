"""A mesh object's vertices as Blender evaluates them (shape keys, modifiers, simulation):
read by the shape-key round trip and the soft-body simulation alike."""

from __future__ import annotations

import bpy
import numpy as np


def evaluated_world_vertices(obj) -> np.ndarray:
    """``obj``'s evaluated vertices at the scene's current frame, world space, float64."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    try:
        local = np.empty(3 * len(mesh.vertices), dtype=np.float32)
        mesh.vertices.foreach_get("co", local)
    finally:
        evaluated.to_mesh_clear()
    world = np.array(evaluated.matrix_world, dtype=np.float64)
    return local.reshape(-1, 3).astype(np.float64) @ world[:3, :3].T + world[:3, 3]
