"""A mesh rig's rest mesh simulated as a soft body in Blender: dropped, squashed, pushed.

The paper simulates a deformable model of its squirrel (Maya nCloth) and maps the result
onto the rig (§6.3, Fig. 9). Here the squirrel's rest mesh goes to a Blender worker
(:mod:`rigmap.rigs.blender.in_blender.softbody` runs the scene: Blender's cloth solver
with pressure, the inflatable-object soft body) and every frame's vertices come back, in
rigmap's centimetres and axes (Y up).

What the solver needs beyond the triangles is built here, from the seed only:

- the mesh is a set of separate closed parts (body, head, teeth, ears, tail …); each part
  is tied to its parent part (:data:`PARENT_PART`) by springs from each of its vertices to
  the ``attach`` nearest vertices of the parent, as a sculpted character is glued together;
- struts: random vertex pairs inside each part (``struts_per_vertex`` per vertex, fewer in
  the body and head), springs through the volume that keep a part's shape (the tail does
  not fold flat) while pressure keeps its volume;
- the vertices below ``pin_below_cm`` (the feet and the base of the body) are pinned: they
  fall with the object and then stay on the ground, so the squashed and pushed squirrel
  bends over its feet instead of rolling away (a standing soft body on two small feet
  topples within seconds).

Nothing here imports bpy; the numbers cross the worker protocol as arrays.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from rigmap.errors import RigmapError

#: each part of the squirrel's mesh and the part it is glued to (None: the root part)
PARENT_PART = {
    "body": None,
    "head": "body",
    "nose": "head",
    "eye_l": "head",
    "eye_r": "head",
    "ear_l": "head",
    "ear_r": "head",
    "tooth_l": "head",
    "tooth_r": "head",
    "arm_l": "body",
    "arm_r": "body",
    "foot_l": "body",
    "foot_r": "body",
    "tail": "body",
}
SOFT_PARTS = ("body", "head")  # parts braced by fewer struts: they squash
WORKER_TIMEOUT_S = 900.0  # one simulation request (ours: the stage's takes about 10 s)


class SimulationError(RigmapError, ValueError):
    """A scenario or a mesh the soft-body simulation cannot run; the message says which."""


@dataclass(frozen=True)
class Cloth:
    """Blender's cloth settings of the soft body (Blender's own units; ours, tuned by eye
    so the squirrel squashes visibly and springs back)."""

    quality: int = 10  # solver steps per frame
    mass: float = 0.05  # kg per vertex
    air_damping: float = 0.3
    tension: float = 5.0
    compression: float = 1.0
    shear: float = 5.0
    bending: float = 1.0
    damping: float = 15.0  # of tension, compression and shear
    pressure: float = 1.0  # uniform pressure force
    collision_distance: float = 0.003  # m
    collision_quality: int = 3


@dataclass(frozen=True)
class Scenario:
    """What happens to the squirrel, in rigmap's units (cm, frames from 1, rigmap axes)."""

    seed: int = 0
    frames: int = 96
    fps: int = 24
    drop_cm: float = 30.0  # height the squirrel falls from
    press_start: int = 20  # gravity rises (a press from above) ...
    press_end: int = 40  # ... and is back to normal here
    press_g: float = 3.5  # times normal gravity at its height
    press_ramp: int = 5
    push_start: int = 52  # the paddle starts moving in ...
    push_end: int = 70  # ... and is deepest here, then withdraws
    push_from_cm: float = -20.0  # paddle centre along the push direction (0: the squirrel)
    push_to_cm: float = -3.0
    push_height_cm: float = 25.0  # height of the paddle's centre
    push_angle_jitter_deg: float = 20.0  # the push direction: +X (rigmap) turned by ± this
    attach: int = 3  # springs from each vertex of a part to its parent part
    struts_per_vertex: float = 1.0
    soft_struts_per_vertex: float = 0.5  # in the body and head
    pin_below_cm: float = 1.2
    ground_friction: float = 20.0
    cloth: Cloth = field(default_factory=Cloth)

    def __post_init__(self) -> None:
        if isinstance(self.cloth, dict):
            object.__setattr__(self, "cloth", Cloth(**self.cloth))
        checks = [
            (self.frames >= 2, f"frames={self.frames}: at least 2"),
            (self.fps > 0, f"fps={self.fps}: a positive number"),
            (self.drop_cm >= 0, f"drop_cm={self.drop_cm}: >= 0"),
            (
                1
                <= self.press_start
                < self.press_start + self.press_ramp
                <= self.press_end - self.press_ramp,
                f"press_start={self.press_start}, press_end={self.press_end}, press_ramp="
                f"{self.press_ramp}: the press must ramp up and down between its frames",
            ),
            (1 <= self.push_start < self.push_end, "push_start must come before push_end"),
            (self.press_g > 0, f"press_g={self.press_g}: a positive factor of gravity"),
            (self.attach >= 1, f"attach={self.attach}: at least 1"),
        ]
        for good, message in checks:
            if not good:
                raise SimulationError(f"simulation scenario: {message}")

    def push_direction(self) -> np.ndarray:
        """The push's unit direction on the ground (rigmap X, Z), drawn from the seed."""
        jitter = np.random.default_rng([self.seed, 1]).uniform(-1.0, 1.0)
        angle = np.radians(self.push_angle_jitter_deg) * jitter
        return np.array([np.cos(angle), np.sin(angle)])

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class SoftBody:
    """What the solver gets besides the triangles: extra springs and pinned vertices."""

    springs: np.ndarray  # (E, 2) vertex pairs, i < j, no duplicates
    pinned: np.ndarray  # (P,) vertex indices


def soft_body(rig, scenario: Scenario) -> SoftBody:
    """Springs and pins of ``rig``'s rest mesh (a mesh rig with ``part_vertices``)."""
    rest = _rest_world(rig)
    parts = dict(getattr(rig, "part_vertices", {}) or {})
    unknown = sorted(set(parts) - set(PARENT_PART))
    if not parts or unknown:
        raise SimulationError(
            f"rig {rig.name!r}: the soft body needs the squirrel's mesh parts "
            f"({', '.join(PARENT_PART)}); unknown parts {unknown}"
        )
    rng = np.random.default_rng([scenario.seed, 0])
    pairs = []
    for name, vertices in parts.items():
        vertices = np.asarray(vertices)
        parent = PARENT_PART[name]
        if parent is not None:
            pairs.append(_attach(rest, vertices, np.asarray(parts[parent]), scenario.attach))
        rate = scenario.soft_struts_per_vertex if name in SOFT_PARTS else scenario.struts_per_vertex
        count = round(rate * len(vertices))
        if count:
            pairs.append(np.stack([rng.choice(vertices, count), rng.choice(vertices, count)], 1))
    springs = np.sort(np.concatenate(pairs), axis=1)
    springs = np.unique(springs[springs[:, 0] != springs[:, 1]], axis=0)
    pinned = np.flatnonzero(rest[:, 1] < scenario.pin_below_cm)
    if len(pinned) == 0:
        raise SimulationError(f"pin_below_cm={scenario.pin_below_cm}: no vertex is that low")
    return SoftBody(springs, pinned)


def _attach(rest: np.ndarray, part: np.ndarray, parent: np.ndarray, k: int) -> np.ndarray:
    distance = np.linalg.norm(rest[part][:, None, :] - rest[parent][None, :, :], axis=2)
    nearest = np.argsort(distance, axis=1, kind="stable")[:, :k]
    return np.stack([np.repeat(part, nearest.shape[1]), parent[nearest].ravel()], axis=1)


def _rest_world(rig) -> np.ndarray:
    """The rest mesh in the world (cm), standing on the ground as the rig places it."""
    return np.asarray(rig.world_vertices(rig.default_controls(1)), dtype=np.float64)[0]


def blender_scenario(scenario: Scenario) -> dict:
    """The scenario in Blender's units and axes (metres, Z up) for the worker."""
    from rigmap.rigs.blender.shape_keys import CM_PER_METRE

    direction = scenario.push_direction()  # rigmap (X, Z) -> Blender (X, -Y)
    cm = 1.0 / CM_PER_METRE
    return {
        "frames": scenario.frames,
        "fps": scenario.fps,
        "drop_m": scenario.drop_cm * cm,
        "ground": {"size_m": 2.0, "friction": scenario.ground_friction, "thickness_m": 0.005},
        "press": {
            "start": scenario.press_start,
            "end": scenario.press_end,
            "g": scenario.press_g,
            "ramp": scenario.press_ramp,
        },
        "push": {
            "direction": [float(direction[0]), float(-direction[1])],
            "start": scenario.push_start,
            "end": scenario.push_end,
            "withdraw": 16,
            "from_m": scenario.push_from_cm * cm,
            "to_m": scenario.push_to_cm * cm,
            "height_m": scenario.push_height_cm * cm,
            "half_thickness_m": 0.04,
            "half_width_m": 0.09,
            "half_height_m": 0.08,
            "friction": 0.0,
        },
        "cloth": asdict(scenario.cloth),
    }


@dataclass(frozen=True)
class SimulatedMesh:
    """Per-frame world vertices of the simulated mesh (cm, rigmap axes) and what made them."""

    vertices: np.ndarray  # (F, V, 3)
    fps: float
    scenario: Scenario
    info: dict  # Blender's: landing frame, version, seconds


def simulate_soft_body(rig, scenario: Scenario, *, blender=None) -> SimulatedMesh:
    """Run ``scenario`` on ``rig``'s rest mesh in a Blender worker; vertices in cm, Y up."""
    from rigmap.rigs.blender.shape_keys import from_blender, to_blender

    body = soft_body(rig, scenario)
    rest = _rest_world(rig)
    arrays = {
        "rest": to_blender(rest),
        "triangles": np.asarray(rig.faces, dtype=np.int64),
        "springs": body.springs,
        "pinned": body.pinned,
    }
    with _worker_pool(blender) as pool:
        info, out = pool.call(
            "simulate_soft_body", {"scenario": blender_scenario(scenario)}, arrays
        )
    vertices = from_blender(out["vertices"])
    if vertices.shape != (scenario.frames, len(rest), 3) or not np.isfinite(vertices).all():
        raise SimulationError(
            f"Blender returned vertices of shape {vertices.shape} (finite: "
            f"{bool(np.isfinite(vertices).all())}), expected ({scenario.frames}, {len(rest)}, 3)"
        )
    info = {k: v for k, v in info.items() if k != "ok"}
    info.update(springs=len(body.springs), pinned=len(body.pinned))
    return SimulatedMesh(vertices, float(scenario.fps), scenario, info)


def _worker_pool(blender):
    from rigmap.rigs.blender.cache import cache_dir
    from rigmap.rigs.blender.environment import find_blender
    from rigmap.rigs.blender.pool import WorkerPool

    command = find_blender(blender)
    # one worker on one CPU: the solver's threads cannot reorder its sums
    return WorkerPool(
        lambda _slot: command.argv("--pin-cpu", "0"),
        workers=1,
        timeout=WORKER_TIMEOUT_S,
        log_dir=cache_dir() / "logs",
    )
