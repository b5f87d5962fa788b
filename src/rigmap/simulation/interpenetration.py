"""Points inside a closed triangle mesh, by the generalised winding number; the squirrel's
teeth inside its body.

The paper's Fig. 9 point: a simulation lets the incisors sink into the chest, while the
rig's collision corrective keeps them out (the neck sinks), so the rig's mapped output has
none inside. The test is the winding number of the body's closed surface about each tooth
vertex (Jacobson et al. 2013: the sum of the signed solid angles its triangles subtend,
over 4π, by Van Oosterom & Strackee's formula): 1 inside, 0 outside, whatever the
triangles' orientation (its absolute value is used) and robust to a few bad triangles.
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.mesh.proximity import winding_numbers as mesh_winding_numbers

INSIDE = 0.5  # |winding number| above this: inside


def winding_numbers(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The winding number of the closed mesh ``(vertices, triangles)`` about each point;
    ``points`` ``(..., 3)`` -> ``(...)`` (the mesh package's solid-angle sum, any shape)."""
    points = np.asarray(points, dtype=np.float64)
    flat = mesh_winding_numbers(
        points.reshape(-1, 3), np.asarray(vertices, dtype=np.float64), np.asarray(triangles)
    )
    return flat.reshape(points.shape[:-1])


def inside(points: np.ndarray, vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Whether each point is inside the closed mesh (``|winding number| > 0.5``)."""
    return np.abs(winding_numbers(points, vertices, triangles)) > INSIDE


def teeth_inside_body(rig, frames: np.ndarray) -> np.ndarray:
    """Per frame, how many of ``rig``'s teeth vertices lie inside its body's closed surface;
    ``frames`` are ``(F, V, 3)`` meshes of the rig's vertices (simulated or the rig's own)."""
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim != 3 or frames.shape[1] != rig.n_vertices:
        raise ValueError(
            f"teeth_inside_body: expected meshes (F, {rig.n_vertices}, 3), got {frames.shape}"
        )
    teeth, faces = np.asarray(rig.teeth_vertices), np.asarray(rig.body_faces)
    return np.array([int(inside(mesh[teeth], mesh, faces).sum()) for mesh in frames])
