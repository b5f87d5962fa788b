"""Where the studio's camera stands, and where a scene point lands on the page.

Each view frames its character from the front; :func:`screen_point` is the same perspective
the page's three.js camera draws with (vertical field of view, the canvas's aspect), so a
test or a benchmark can put the mouse on a gizmo it knows only in scene coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FOV_RAD = np.deg2rad(50.0)  # ours: a portrait lens, little distortion at the frame's edges
MARGIN = 1.35  # ours: the character fills 1/1.35 of the frame's height
#: the GUI panel covers the page's right side: the character is drawn this share of the
#: frame's width left of the middle, for a page about 1.4 times wider than high (ours)
LEFT_SHIFT, ASPECT = 0.2, 1.4


@dataclass(frozen=True)
class CameraPose:
    position: np.ndarray  # (3,) scene units
    look_at: np.ndarray  # (3,)
    up: np.ndarray  # (3,)
    fov: float = FOV_RAD  # vertical, radians


def front_camera(points, *, fov: float = FOV_RAD, left_shift: float = LEFT_SHIFT) -> CameraPose:
    """A camera on +Z looking at the middle of ``points`` ``(N, 3)`` (scene units, Y up),
    far enough for their height (and width) to fit, the character ``left_shift`` of the
    frame's width left of the middle (viser's panel covers the right; 0 on a page without)."""
    points = np.asarray(points, dtype=np.float64)
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2
    extent = max(high[1] - low[1], high[0] - low[0], 1e-3)
    distance = MARGIN * extent / (2 * np.tan(fov / 2)) + (high[2] - low[2]) / 2
    aim = centre + np.array([left_shift * 2 * distance * np.tan(fov / 2) * ASPECT, 0.0, 0.0])
    position = aim + np.array([0.0, 0.0, distance])
    return CameraPose(position, aim, np.array([0.0, 1.0, 0.0]), fov)


def apply(camera: CameraPose, target) -> None:
    """Set a viser camera (a client's, or the server's initial one) to ``camera``."""
    target.fov = camera.fov
    target.position = tuple(camera.position)
    target.look_at = tuple(camera.look_at)
    if hasattr(target, "up_direction"):
        target.up_direction = tuple(camera.up)
    else:
        target.up = tuple(camera.up)


def aim_every_page(camera: CameraPose, server) -> None:
    """Every open page's camera, and a new page's, set to ``camera``."""
    apply(camera, server.initial_camera)
    for client in server.get_clients().values():
        apply(camera, client.camera)


def screen_point(camera: CameraPose, point, width: float, height: float) -> tuple[float, float]:
    """Pixel ``(x, y)`` from the canvas's top-left of scene ``point`` (perspective)."""
    forward = camera.look_at - camera.position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, camera.up)
    right = right / np.linalg.norm(right)
    up = np.cross(right, forward)
    v = np.asarray(point, dtype=np.float64) - camera.position
    depth = float(v @ forward)
    if depth <= 0:
        raise ValueError("the point is behind the camera")
    half = np.tan(camera.fov / 2)
    ndc_x = float(v @ right) / (depth * half * width / height)
    ndc_y = float(v @ up) / (depth * half)
    return (ndc_x + 1) / 2 * width, (1 - ndc_y) / 2 * height


def camera_message(camera) -> dict:
    """A :class:`CameraPose` as the studio's own pages read it (JSON)."""
    return {
        "position": camera.position.tolist(),
        "look_at": camera.look_at.tolist(),
        "up": camera.up.tolist(),
        "fov": float(camera.fov),
    }
