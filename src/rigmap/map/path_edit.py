"""Locomotion bent along a user's path and set on a terrain (paper §6.3, Fig. 7).

The paper bends synthesised locomotion along a curve, projects it onto terrain, and maps
the edited joints back onto the rig. :class:`PathEdit` does this to world joint positions
``(F, J, 3)`` (cm, rig axes, Y up), in four steps:

1. optionally lengthened by looping its own cycle (:mod:`rigmap.map.cycles`);
2. bent: the root's progress along its straight travel is taken as arc length on the
   path, every frame moved rigidly so its root ground point sits on the path (with its
   sideways sway kept along the path's normal) and turned by the path tangent's heading
   against the clip's (:func:`bend`);
3. stance feet held: each planted foot joint (found on the straight clip) is held at its
   mean position over the plant, the hold eased in and out over the frames around it,
   so bending adds no foot skate (:func:`hold_stance`);
4. set on the terrain: each foot joint (with the joints below it) raised by the terrain
   under itself, the rest of the body by the lowest terrain under the feet, so no leg
   must stretch (:func:`onto_terrain`).

A straight path along the clip's own travel on flat ground gives the input back.
:func:`path_scores` measures skate and penetration against the terrain.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.map.contacts import Contacts, contact_floors, detect_contacts, foot_skate
from rigmap.map.cycles import GROUND, find_cycle, loop_cycle

UP = 1
MIN_TRAVEL_CM = 10.0  # ours: a clip whose root moves less has no direction to bend
HOLD_EASE_S = 0.15  # ours: a hold eases in and out over this long around each plant
# ours: the corpus walk slides its planted feet back by about 2 cm per frame, so a plant
# is found by its height with a speed bound above that slide (swing is about twice it)
STANCE_SPEED_CM_S = 60.0


class PathEditError(RigmapError, ValueError):
    """A path file, terrain or clip the path edit cannot use."""


@dataclass(frozen=True)
class GroundPath:
    """A smooth curve through ``points`` ``(N, 2)`` (X, Z cm), sampled densely by arc length."""

    points: np.ndarray
    source: str = ""
    samples: int = 4000

    def __post_init__(self) -> None:
        points = np.asarray(self.points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2 or len(points) < 2:
            raise PathEditError(
                f"path {self.source}: points of shape {points.shape}, not (N>=2, 2)"
            )
        if not np.isfinite(points).all():
            raise PathEditError(f"path {self.source}: points hold NaN or infinite values")
        if np.any(np.linalg.norm(np.diff(points, axis=0), axis=1) < 1e-9):
            raise PathEditError(f"path {self.source}: two consecutive points are the same")

    def _dense(self) -> tuple[np.ndarray, np.ndarray]:
        from scipy.interpolate import make_interp_spline

        points = np.asarray(self.points, dtype=np.float64)
        chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        spline = make_interp_spline(chord, points, k=min(3, len(points) - 1))
        dense = spline(np.linspace(0.0, chord[-1], self.samples))
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
        return arc, dense

    @property
    def length_cm(self) -> float:
        return float(self._dense()[0][-1])

    def at(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points ``(N, 2)`` and unit tangents ``(N, 2)`` at arc lengths ``s`` (cm); past
        either end the path goes on straight along its end tangent."""
        arc, dense = self._dense()
        s = np.asarray(s, dtype=np.float64)
        tangent = np.gradient(dense, arc, axis=0)
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        inside = np.clip(s, 0.0, arc[-1])
        point = np.stack([np.interp(inside, arc, dense[:, k]) for k in range(2)], axis=-1)
        t = np.stack([np.interp(inside, arc, tangent[:, k]) for k in range(2)], axis=-1)
        t /= np.linalg.norm(t, axis=1, keepdims=True)
        return point + (s - inside)[:, None] * t, t


def read_path(path: str | Path) -> GroundPath:
    """A path from YAML or JSON: ``points: [[x, z], ...]`` in ``unit`` (cm, m; default cm)."""
    import yaml

    path = Path(path)
    if not path.is_file():
        raise PathEditError(f"path file {path} does not exist")
    if path.suffix.lower() not in (".yaml", ".yml", ".json"):
        raise PathEditError(f"path file {path}: expected .yaml, .yml or .json")
    try:
        text = path.read_text()
        data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
    except (OSError, ValueError, yaml.YAMLError) as error:
        raise PathEditError(f"path file {path}: unreadable ({error})".splitlines()[0]) from None
    if not isinstance(data, dict) or "points" not in data:
        raise PathEditError(f"path file {path}: expected a mapping with points: [[x, z], ...]")
    unit = {"cm": 1.0, "m": 100.0}.get(data.get("unit", "cm"))
    if unit is None:
        raise PathEditError(f"path file {path}: unit {data.get('unit')!r}, expected cm or m")
    try:
        points = np.asarray(data["points"], dtype=np.float64) * unit
    except (TypeError, ValueError):
        raise PathEditError(f"path file {path}: points must be [[x, z], ...] numbers") from None
    return GroundPath(points, str(path))


def heading(direction: np.ndarray) -> np.ndarray:
    """Heading (rad) about +Y of ground directions ``(..., 2)`` (X, Z): 0 along +Z."""
    return np.arctan2(direction[..., 0], direction[..., 1])


def bend(world: np.ndarray, root: int, path: GroundPath) -> np.ndarray:
    """Every frame moved rigidly onto ``path``: see the module docstring (step 2)."""
    world = np.asarray(world, dtype=np.float64)
    ground = world[:, root][:, GROUND]
    travel = ground[-1] - ground[0]
    if np.linalg.norm(travel) < MIN_TRAVEL_CM:
        raise PathEditError(
            f"the clip's root travels {np.linalg.norm(travel):.1f} cm: no direction to bend "
            "along a path (give locomotion)"
        )
    u = travel / np.linalg.norm(travel)
    n = np.array([u[1], -u[0]])  # u turned by -90° about +Y
    s, d = (ground - ground[0]) @ u, (ground - ground[0]) @ n
    point, tangent = path.at(s)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=-1)
    turn = heading(tangent) - heading(u)
    cos, sin = np.cos(turn)[:, None], np.sin(turn)[:, None]
    rel = world[:, :, GROUND] - ground[:, None]
    out = world.copy()
    out[:, :, 0] = rel[..., 0] * cos + rel[..., 1] * sin
    out[:, :, 2] = -rel[..., 0] * sin + rel[..., 1] * cos
    out[:, :, GROUND] += (point + d[:, None] * normal)[:, None]
    return out


def chain(parents, joint: int, stop: set[int]) -> list[int]:
    """``joint`` and every joint below it, not entering the subtree of a joint in ``stop``."""
    parents = np.asarray(parents)
    below, frontier = [joint], [joint]
    while frontier:
        children = [int(c) for c in np.flatnonzero(np.isin(parents, frontier)) if c not in stop]
        below += children
        frontier = children
    return below


def hold_stance(
    world: np.ndarray, parents, contacts: Contacts, names, ease_frames: int
) -> np.ndarray:
    """Each planted foot joint (and the joints below it that are no foot joint themselves)
    held at its mean ground position over each plant, eased in and out over
    ``ease_frames`` frames around it (never into another plant of that joint)."""
    out = np.array(world, dtype=np.float64, copy=True)
    feet = {names.index(f) for f in contacts.feet}
    for k, foot in enumerate(contacts.feet):
        j = names.index(foot)
        shift = np.zeros((len(out), 2))
        runs = contacts.intervals(k)
        for r, (first, last) in enumerate(runs):
            pin = out[first : last + 1, j][:, GROUND].mean(axis=0)
            shift[first : last + 1] = pin - out[first : last + 1, j][:, GROUND]
            before = runs[r - 1][1] if r else -1
            after = runs[r + 1][0] if r + 1 < len(runs) else len(out)
            for step in range(1, ease_frames + 1):
                weight = 1 - step / (ease_frames + 1)
                if first - step > before + (first - before) // 2:
                    shift[first - step] = weight * shift[first]
                if last + step < after - (after - last) // 2:
                    shift[last + step] = weight * shift[last]
        moved = chain(parents, j, feet - {j})
        out[:, np.asarray(moved)[:, None], np.asarray(GROUND)[None]] += shift[:, None]
    return out


def onto_terrain(world: np.ndarray, parents, feet: list[int], terrain) -> np.ndarray:
    """Foot joints (with the joints below them) up by the terrain under each joint, the
    rest of the body up by the lowest terrain under the feet (step 4)."""
    out = np.array(world, dtype=np.float64, copy=True)
    ground = terrain.height(out[..., 0], out[..., 2])  # (F, J)
    chains = sorted({c for f in feet for c in chain(parents, f, set())})
    body = np.setdiff1d(np.arange(out.shape[1]), chains)
    out[:, body, UP] += ground[:, feet].min(axis=1)[:, None]
    out[:, chains, UP] += ground[:, chains]
    return out


@dataclass(frozen=True)
class PathEdit:
    """A path, a terrain, and how the clip is looped first (``loop_seconds`` None: not)."""

    path: GroundPath
    terrain: object  # a rigmap.map.terrain Procedural or HeightField (``height(x, z)``)
    loop_seconds: float | None = None
    blend_seconds: float = 0.25  # ours: the seam's blend
    stance_speed_cm_s: float = STANCE_SPEED_CM_S

    def apply(self, world, names, parents, feet, fps) -> EditedClip:
        """The edited clip of world joints ``world`` ``(F, J, 3)`` named ``names`` (each
        one's parent index among them in ``parents``, -1: none), ``feet`` the contact joints."""
        names = list(names)
        root = int(np.argmin([_depth(parents, j) for j in range(len(names))]))
        world = np.asarray(world, dtype=np.float64)
        cycle = None
        if self.loop_seconds is not None:
            cycle = find_cycle(world, root, fps)
            frames = max(2, round(self.loop_seconds * fps))
            blend = min(cycle.period, max(1, round(self.blend_seconds * fps)))
            world = loop_cycle(world, root, cycle, frames, blend)
        feet = [f for f in feet if f in names]
        if not feet:
            raise PathEditError(f"no foot joint among the clip's joints {names}")
        contacts = detect_contacts(
            world, feet, names, fps, speed_tolerance_cm_s=self.stance_speed_cm_s
        )
        bent = bend(world, root, self.path)
        held = hold_stance(bent, parents, contacts, names, round(HOLD_EASE_S * fps))
        foot_index = [names.index(f) for f in feet]
        edited = onto_terrain(held, parents, foot_index, self.terrain)
        floors = contact_floors(world, contacts, names)
        return EditedClip(tuple(names), world, bent, edited, contacts, floors, cycle, root)


def _depth(parents, j: int) -> int:
    depth = 0
    while parents[j] >= 0:
        j, depth = parents[j], depth + 1
    return depth


@dataclass(frozen=True)
class EditedClip:
    """The straight (looped) clip, it bent, the edit, and the plants found on it."""

    names: tuple[str, ...]
    straight: np.ndarray  # (F, J, 3)
    bent: np.ndarray  # bent only: no hold, flat ground
    edited: np.ndarray  # bent, held, on the terrain
    contacts: Contacts
    floors: np.ndarray  # per foot joint: its standing height over flat ground (cm)
    cycle: object = None  # rigmap.map.cycles.Cycle when looped
    root: int = 0
    extra: dict = field(default_factory=dict)


def penetration(world, clip: EditedClip, terrain, names=None) -> tuple[float, float]:
    """Deepest and mean depth (cm) of the foot joints below their standing height over the
    terrain, on every frame (mean over frames and feet, 0 where above)."""
    names = list(names or clip.names)
    cols = [names.index(f) for f in clip.contacts.feet]
    foot = np.asarray(world)[:, cols]
    floor = terrain.height(foot[..., 0], foot[..., 2]) + clip.floors[None]
    depth = np.maximum(floor - foot[..., UP], 0.0)
    return float(depth.max(initial=0.0)), float(depth.mean())


def path_scores(clip: EditedClip, terrain, mapped=None, mapped_names=None) -> dict:
    """Skate (cm/frame on plants) of the straight clip; skate and penetration (cm) of the
    bent-only and edited clip, and of ``mapped`` (the rig's joints, named ``mapped_names``)
    with its joint error against the edit on those joints."""
    rows = {
        "straight": {
            "foot_skate_cm_per_frame": foot_skate(clip.straight, clip.contacts, list(clip.names))
        }
    }
    for name, world, names in (
        ("bent_only", clip.bent, clip.names),
        ("edited", clip.edited, clip.names),
        ("mapped", mapped, mapped_names),
    ):
        if world is None:
            continue
        deepest, mean = penetration(world, clip, terrain, names)
        rows[name] = {
            "foot_skate_cm_per_frame": foot_skate(world, clip.contacts, list(names)),
            "penetration_max_cm": deepest,
            "penetration_mean_cm": mean,
        }
    if mapped is not None:
        cols = [clip.names.index(n) for n in mapped_names]
        gap = np.linalg.norm(np.asarray(mapped) - clip.edited[:, cols], axis=2)
        rows["mapped"]["joint_error_rms_cm"] = float(np.sqrt((gap**2).mean()))
        rows["mapped"]["joint_error_max_cm"] = float(gap.max())
    return rows
