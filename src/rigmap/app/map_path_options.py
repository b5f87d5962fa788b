"""``rigmap map``'s path edit (paper Fig. 7): its options checked, the clip edited, its scores.

``map.path`` (a YAML/JSON file of ground points) turns the edit on: the input clip, or
``map.corpus_clip`` of the rig's train corpus, is looped to ``map.loop_seconds`` (null: not
looped), bent along the path, its feet set on ``map.terrain`` (``flat``, ``slope``,
``sine`` with ``map.terrain_shape``, or a height-field ``.npz``/``.npy`` with
``map.terrain_cell_cm``) (:mod:`rigmap.map.path_edit`), then mapped as ``rigmap map`` maps
any clip. Beside the clip's outputs it writes ``path_edit.json`` (skate, penetration, joint
error), ``path_frames.csv`` and ``path_edit.png``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.errors import RigmapError
from rigmap.map.joint_map import MappedTargets
from rigmap.map.path_edit import EditedClip, PathEdit, path_scores, read_path
from rigmap.map.terrain import NAMES, Procedural, read_height_field
from rigmap.store import Layout, atomic_file, json_ready, write_json_atomic

SHAPE_KEYS = ("slope_percent", "heading_deg", "amplitude_cm", "wavelength_cm")


class PathOptionError(RigmapError, ValueError):
    """A ``map.path``/``terrain``/``loop_seconds`` option that cannot be used."""


def _number(options: Mapping, key: str, low: float, *, allow_none: bool = True):
    value = options.get(key)
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > low:
        raise PathOptionError(f"map.{key}={value!r}: expected a number > {low:g}")
    if not np.isfinite(value):
        raise PathOptionError(f"map.{key}={value!r}: expected a finite number")
    return float(value)


def terrain_from_options(options: Mapping):
    """``map.terrain``: a name of :data:`NAMES` (shaped by ``map.terrain_shape``) or a file."""
    name = options.get("terrain") or "flat"
    shape = dict(options.get("terrain_shape") or {})
    unknown = sorted(set(shape) - set(SHAPE_KEYS))
    if unknown:
        raise PathOptionError(f"map.terrain_shape: unknown keys {unknown}; known: {SHAPE_KEYS}")
    if str(name) in NAMES:
        try:
            return Procedural(str(name), **{k: float(v) for k, v in shape.items()})
        except (TypeError, ValueError) as error:
            raise PathOptionError(f"map.terrain_shape: {error}") from None
    if Path(str(name)).suffix.lower() not in (".npz", ".npy"):
        raise PathOptionError(
            f"map.terrain={name!r}: expected one of {', '.join(NAMES)} or a .npz/.npy height field"
        )
    try:
        return read_height_field(name, _number(options, "terrain_cell_cm", 0.0))
    except RigmapError as error:
        raise PathOptionError(f"map.terrain: {error}") from None


def path_edit_from_options(options: Mapping) -> PathEdit | None:
    """The edit ``map.path`` asks for (None without it), every option checked first."""
    loop = _number(options, "loop_seconds", 0.0)
    blend = _number(options, "loop_blend_seconds", 0.0)
    if not options.get("path"):
        if loop is not None or options.get("terrain") not in (None, "flat"):
            raise PathOptionError("map.terrain and map.loop_seconds need map.path=<points file>")
        return None
    try:
        path = read_path(options["path"])
    except RigmapError as error:
        raise PathOptionError(f"map.path: {error}") from None
    edit = PathEdit(path, terrain_from_options(options), loop)
    return dataclasses.replace(edit, blend_seconds=blend) if blend else edit


def corpus_targets(config: Mapping, rig, clip: str) -> MappedTargets:
    """Every joint of ``clip`` in the rig's train poses (world cm) as targets."""
    from rigmap.animation.posing import PoseTable

    layout = Layout.from_paths(config.get("paths"))
    poses = PoseTable.read(
        layout.poses(rig.name, "train"), rig=rig.name, n_joints=rig.n_joints, split="train"
    )
    rows = np.flatnonzero(poses.table["clip"].to_numpy() == clip)
    if rows.size == 0:
        raise PathOptionError(
            f"map.corpus_clip={clip!r}: not a train clip of {rig.name!r} ({poses.clip_names})"
        )
    world = poses.positions()[rows] + poses.cog()[rows][:, None, :]
    names = tuple(rig.joint_names)
    return MappedTargets(rig.name, names, world, float(poses.metadata["fps"]), clip, 1.0, (), ())


def edit_clips(edit: PathEdit, rig, clips, feet) -> tuple[list[MappedTargets], dict]:
    """Each clip edited; returns the edited targets and ``{source: EditedClip}``."""
    from rigmap.map.preview import subset_parents

    out, edited = [], {}
    for targets in clips:
        parents = subset_parents(rig, targets.joint_names)
        try:
            clip = edit.apply(targets.positions, targets.joint_names, parents, feet, targets.fps)
        except RigmapError as error:
            raise PathOptionError(f"{targets.source}: path edit: {error}") from None
        edited[targets.source] = clip
        out.append(dataclasses.replace(targets, positions=clip.edited))
    return out, edited


def path_record(edit: PathEdit, clip: EditedClip, result) -> dict:
    """The edit's settings and scores (edited input and the mapped rig) as JSON."""
    scores = path_scores(clip, edit.terrain, result.achieved, result.joint_names)
    cycle = clip.cycle
    return json_ready(
        {
            "rig": result.rig,
            "source": result.source,
            "frames": len(clip.edited),
            "fps": result.fps,
            "path": edit.path.source,
            "path_length_cm": edit.path.length_cm,
            "root_travel_cm": float(
                np.linalg.norm(np.diff(clip.edited[:, clip.root, ::2], axis=0), axis=1).sum()
            ),
            **edit.terrain.describe(),
            "loop_seconds": edit.loop_seconds,
            "cycle": dataclasses.asdict(cycle) if cycle is not None else None,
            "feet": list(clip.contacts.feet),
            "mapped_joints": len(result.joint_names),
            "scores": scores,
            "units": "skate: cm per frame on planted frames; penetration: cm below the foot "
            "joint's standing height over the terrain; joint error: cm RMS on the mapped joints",
        }
    )


def write_path_outputs(staging: Path, edit: PathEdit, clip: EditedClip, result) -> dict:
    """``path_edit.json``, ``path_frames.csv`` (per frame: joint error) and ``path_edit.png``."""
    from rigmap.map.path_figure import write_path_figure

    record = path_record(edit, clip, result)
    write_json_atomic(staging / "path_edit.json", record)
    cols = [clip.names.index(n) for n in result.joint_names]
    gap = np.linalg.norm(result.achieved - clip.edited[:, cols], axis=2)
    frames = pd.DataFrame(
        {"frame": np.arange(len(gap)), "joint_error_cm": np.sqrt((gap**2).mean(1))}
    )
    with atomic_file(staging / "path_frames.csv", suffix=".csv") as temporary:
        frames.to_csv(temporary, index=False, float_format="%.6g")
    write_path_figure(
        staging / "path_edit.png",
        clip,
        result.achieved,
        result.joint_names,
        edit.terrain,
        record["scores"],
    )
    return record


def with_path_outputs(extra, edit: PathEdit, clip: EditedClip, result, staging: Path) -> None:
    """``extra(staging)`` (the clip's other outputs), then the path edit's."""
    extra(staging)
    write_path_outputs(staging, edit, clip, result)
