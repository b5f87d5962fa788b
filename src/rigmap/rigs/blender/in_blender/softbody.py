"""A closed mesh simulated as a soft body by Blender's own solver; its vertices read back.

Runs inside Blender (imports bpy). The main process (:mod:`rigmap.simulation.soft_body`)
sends Blender-ready numbers: the rest vertices in metres in Blender's Z-up axes standing on
the ground (z = 0), the triangles, extra springs (vertex pairs: the loose edges that tie a
mesh's separate parts together and brace their insides), the vertices pinned to the ground,
and the scenario's settings. Nothing here converts units or draws a random number.

The soft body is Blender's cloth modifier with pressure (the inflatable-object model: a
closed surface whose volume pushes back, plus every edge a spring; the loose edges are
springs too), as a squashy character is simulated in Blender (Maya's nCloth, which the
paper used, is the same kind of solver). The scene, in order:

1. the mesh falls from ``drop_m`` (its object keyed on a free-fall curve, the pinned
   vertices — the feet — held to it) and lands on the ground: the free vertices carry on
   and squash against the pinned ones, then spring back;
2. gravity rises to ``press_g`` times its value and back (a press from above: the body
   sags and buckles onto its feet), keyed on the scene's gravity;
3. a paddle (a collision box) pushes the upper body along ``push_direction`` and withdraws.

The ground is a collision plane at z = 0. Every step is Blender's: the result is the
evaluated mesh of the cloth modifier at each frame, in world coordinates. Blender's cloth
solver is deterministic: the same input gives the same vertices (tests/test_simulate_blender.py).
"""

from __future__ import annotations

import math
import time

import bpy
import numpy as np

GRAVITY = 9.81  # m/s², Blender's default scene gravity


def new_empty_scene(fps: int):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = int(fps)
    scene.render.fps_base = 1.0
    return scene


def soft_mesh_object(scene, rest, triangles, springs, pinned):
    """The mesh with its springs as loose edges and a ``pin`` vertex group."""
    mesh = bpy.data.meshes.new("soft_body")
    mesh.from_pydata(
        np.asarray(rest, dtype=np.float64).tolist(),
        np.asarray(springs, dtype=np.int64).tolist(),
        np.asarray(triangles, dtype=np.int64).tolist(),
    )
    mesh.update(calc_edges=True)
    if len(mesh.vertices) != len(rest):
        raise ValueError(f"Blender built {len(mesh.vertices)} vertices from {len(rest)}")
    obj = bpy.data.objects.new("soft_body", mesh)
    scene.collection.objects.link(obj)
    group = obj.vertex_groups.new(name="pin")
    group.add([int(i) for i in pinned], 1.0, "REPLACE")
    return obj


def collision_box(scene, name: str, half_size, keys, *, friction: float, thickness: float):
    """A closed box collider keyed at ``keys`` = [(frame, (x, y, z)), ...]."""
    mesh = bpy.data.meshes.new(name)
    x, y, z = half_size
    corners = [(sx * x, sy * y, sz * z) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(corners, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    _collider(obj, friction, thickness)
    for frame, location in keys:
        obj.location = location
        obj.keyframe_insert("location", frame=int(frame))
    return obj


def ground_plane(scene, size: float, *, friction: float, thickness: float):
    mesh = bpy.data.meshes.new("ground")
    mesh.from_pydata(
        [(-size, -size, 0.0), (size, -size, 0.0), (size, size, 0.0), (-size, size, 0.0)],
        [],
        [(0, 1, 2, 3)],
    )
    obj = bpy.data.objects.new("ground", mesh)
    scene.collection.objects.link(obj)
    _collider(obj, friction, thickness)
    return obj


def _collider(obj, friction: float, thickness: float) -> None:
    obj.modifiers.new("collision", "COLLISION")
    obj.collision.cloth_friction = float(friction)
    obj.collision.thickness_outer = float(thickness)
    obj.collision.use_normal = True  # push along the face normal: nothing tunnels through


def key_drop(obj, drop_m: float, fps: float) -> int:
    """Key the object on a free fall from ``drop_m`` to the ground; the landing frame."""
    landing = math.ceil(math.sqrt(2 * drop_m / GRAVITY) * fps) + 1 if drop_m > 0 else 1
    for frame in range(1, landing + 1):
        t = (frame - 1) / fps
        obj.location = (0.0, 0.0, max(drop_m - 0.5 * GRAVITY * t * t, 0.0))
        obj.keyframe_insert("location", frame=frame)
    return landing


def key_press(scene, start: int, end: int, factor: float, ramp: int) -> None:
    """Scene gravity times ``factor`` between ``start`` and ``end`` (ramped over ``ramp``)."""
    for frame, k in (
        (1, 1.0),
        (start, 1.0),
        (start + ramp, factor),
        (end - ramp, factor),
        (end, 1.0),
    ):
        scene.gravity = (0.0, 0.0, -GRAVITY * k)
        scene.keyframe_insert("gravity", frame=int(frame))


def cloth_modifier(obj, cloth: dict, frames: int):
    """The cloth modifier with pressure: the soft body's material (``cloth``'s numbers)."""
    modifier = obj.modifiers.new("soft_body", "CLOTH")
    settings = modifier.settings
    settings.quality = int(cloth["quality"])
    settings.mass = float(cloth["mass"])
    settings.air_damping = float(cloth["air_damping"])
    settings.tension_stiffness = float(cloth["tension"])
    settings.compression_stiffness = float(cloth["compression"])
    settings.shear_stiffness = float(cloth["shear"])
    settings.bending_stiffness = float(cloth["bending"])
    damping = float(cloth["damping"])
    settings.tension_damping = settings.compression_damping = settings.shear_damping = damping
    settings.use_pressure = float(cloth["pressure"]) > 0
    settings.uniform_pressure_force = float(cloth["pressure"])
    settings.vertex_group_mass = "pin"  # the pinned vertices follow the object (the feet)
    collision = modifier.collision_settings
    collision.use_collision = True
    collision.distance_min = float(cloth["collision_distance"])
    collision.collision_quality = int(cloth["collision_quality"])
    collision.use_self_collision = False  # parts pass through each other (teeth into chest)
    modifier.point_cache.frame_start = 1
    modifier.point_cache.frame_end = int(frames)
    return modifier


def simulate(rest, triangles, springs, pinned, scenario: dict) -> tuple[dict, dict]:
    """Run the scenario (module docstring) and read every frame's vertices back.

    Returns the info (frames, landing frame, Blender's version, seconds) and
    ``{"vertices": (frames, V, 3)}`` in world metres, Blender's axes.
    """
    from evaluated_mesh import evaluated_world_vertices

    started = time.perf_counter()
    frames, fps = int(scenario["frames"]), float(scenario["fps"])
    scene = new_empty_scene(int(fps))
    scene.frame_start, scene.frame_end = 1, frames
    obj = soft_mesh_object(scene, rest, triangles, springs, pinned)
    landing = key_drop(obj, float(scenario["drop_m"]), fps)
    ground = scenario["ground"]
    ground_plane(
        scene, float(ground["size_m"]), friction=ground["friction"], thickness=ground["thickness_m"]
    )
    press = scenario["press"]
    key_press(scene, int(press["start"]), int(press["end"]), float(press["g"]), int(press["ramp"]))
    _paddle(scene, scenario["push"], ground)
    cloth_modifier(obj, scenario["cloth"], frames)
    vertices = np.empty((frames, len(rest), 3))
    for frame in range(1, frames + 1):
        scene.frame_set(frame)  # in order: the cloth cache steps one frame at a time
        vertices[frame - 1] = evaluated_world_vertices(obj)
    info = {
        "frames": frames,
        "landing_frame": landing,
        "blender_version": bpy.app.version_string,
        "seconds": time.perf_counter() - started,
    }
    return info, {"vertices": vertices}


def _paddle(scene, push: dict, ground: dict):
    """A box that comes in along ``direction`` from ``from_m`` to ``to_m`` and goes back."""
    dx, dy = (float(v) for v in push["direction"])
    height = float(push["height_m"])

    def at(distance: float):
        return (dx * distance, dy * distance, height)

    start, end = int(push["start"]), int(push["end"])
    keys = [(1, at(push["from_m"])), (start, at(push["from_m"])), (end, at(push["to_m"]))]
    keys.append((end + int(push["withdraw"]), at(push["from_m"] - 0.1)))
    half = (
        float(push["half_thickness_m"]),
        float(push["half_width_m"]),
        float(push["half_height_m"]),
    )
    paddle = collision_box(
        scene, "paddle", half, keys, friction=push["friction"], thickness=ground["thickness_m"]
    )
    paddle.rotation_euler = (0.0, 0.0, math.atan2(dy, dx))  # its thin side faces the push
    return paddle
