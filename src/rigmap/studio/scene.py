"""A rig's skeleton in the studio's scene: joints as points, bones as line segments.

rigmap's world is Y-up in centimetres; the scene is Y-up (``set_up_direction("+y")``) in
metres, so viser's default camera, grid and gizmo sizes fit a 1-2 m character.
"""

from __future__ import annotations

import numpy as np

CM_PER_SCENE_UNIT = 100.0
#: a gizmo's size as a share of the character's height (ours: grabbable, not in the way)
GIZMO_SHARE = 0.085


def to_scene(points_cm) -> np.ndarray:
    return np.asarray(points_cm, dtype=np.float64) / CM_PER_SCENE_UNIT


def from_scene(points) -> np.ndarray:
    return np.asarray(points, dtype=np.float64) * CM_PER_SCENE_UNIT


def world_joints(rig, controls) -> np.ndarray:
    """Joint positions ``(J, 3)`` in the world (cm) of one full control row (a built-in
    rig's TorchScript trace where it has one: 2-3 ms on the biped against 6.5 eager)."""
    row = np.asarray(controls, dtype=np.float64)[None]
    traced = getattr(rig, "traced_pose", None)
    if traced is not None:
        import torch

        with torch.no_grad():
            positions, cog, _ = traced(1)(torch.as_tensor(row))
        return (positions + cog[:, None, :]).numpy()[0]
    pose = rig.pose(row)
    return (np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :])[0]


def bone_pairs(rig) -> np.ndarray:
    """``(B, 2)`` joint indices of the bones (each joint to its parent)."""
    parents = [] if rig.parents is None else [int(p) for p in rig.parents]
    pairs = [(j, p) for j, p in enumerate(parents) if p >= 0]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def has_surface(rig) -> bool:
    """A mesh rig: one with ``world_vertices`` and faces, drawn as its surface."""
    return (
        callable(getattr(rig, "world_vertices", None)) and getattr(rig, "faces", None) is not None
    )


def world_pose(rig, controls) -> tuple[np.ndarray, np.ndarray | None]:
    """Joints ``(J, 3)`` and, for a mesh rig (:func:`has_surface`), every vertex ``(V, 3)``,
    in the world (cm), from one evaluation of the rig: a mesh rig's joints are some of its
    vertices."""
    if has_surface(rig):
        surface = np.asarray(rig.world_vertices(np.asarray(controls, dtype=np.float64)))
        return surface[np.asarray(rig.joint_vertices)], surface
    return world_joints(rig, controls), None


def add_surface(scene, name: str, vertices, faces, color):
    """A mesh rig's surface in ``scene`` (scene units): lit by the scene's direct lights and
    no shadows, as :func:`light_for_software_rendering` sets the scene."""
    return scene.add_mesh_simple(
        name,
        vertices=vertices,
        faces=np.asarray(faces),
        color=color,
        cast_shadow=False,
        receive_shadow=False,
    )


def light_for_software_rendering(scene) -> None:
    """Direct lights only: no image-based lighting (viser's default environment map) and no
    shadow pass. On a machine without a GPU (Chromium's SwiftShader) they cost most of a
    frame: with the face's mesh on screen the page drew 9-12 frames/s with them and 30
    without (measured, 1000 x 700 page, 2 cores)."""
    scene.configure_environment_map(hdri=None)
    scene.configure_default_lights(enabled=True, cast_shadow=False)


class SkeletonDrawing:
    """One skeleton under ``name`` in ``scene``; :meth:`update` moves it in place."""

    def __init__(self, scene, name: str, rig, joints_cm, *, color=(40, 90, 200), size=0.02):
        self.bones = bone_pairs(rig)
        points = to_scene(joints_cm)
        self.points = scene.add_point_cloud(
            f"{name}/joints", points=points, colors=color, point_size=size, point_shape="circle"
        )
        self.lines = scene.add_line_segments(
            f"{name}/bones",
            points=self._segments(points),
            colors=color,
            thickness=3.0,
            thickness_units="screen",
        )

    def _segments(self, points: np.ndarray) -> np.ndarray:
        if len(self.bones) == 0:
            return np.zeros((0, 2, 3))
        return points[self.bones]

    def update(self, joints_cm) -> None:
        points = to_scene(joints_cm)
        self.points.points = points
        self.lines.points = self._segments(points)

    @property
    def visible(self) -> bool:
        return bool(self.points.visible)

    @visible.setter
    def visible(self, value: bool) -> None:
        self.points.visible = value
        self.lines.visible = value

    def remove(self) -> None:
        self.points.remove()
        self.lines.remove()
