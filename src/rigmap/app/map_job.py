"""``rigmap map`` and ``rigmap pose``: their config composed (:func:`map_config`), then the work
from the plain mapping.

:func:`map_from_config` maps one input onto a rig: a BVH file, a folder of BVH files (a
batch, with a progress bar), or a joint-tracks file (parquet, CSV or npz in the stated
unit). Every input is read and retargeted before anything is fitted, so a bad file
stops the run in its first seconds; then the partial-input mapping for the retarget
map's joints is obtained (:mod:`rigmap.map.subset_model`: cached in
``models/<rig>/map-<subset>/``, refitted when stale) and each clip is mapped
(:func:`rigmap.map.clip.map_clip`) into ``<out>/<clip>/``, written whole or not at all:
controls, per-frame error and confidence, keys, a BVH of the result, a summary, a
preview, and for a Blender rig a copy of its ``.blend`` with the reduced keys as an action.
The input's path through these functions is listed in ``docs/architecture.md``
("Following `rigmap map`") and checked by ``tests/test_map_app.py``.

:func:`pose_from_config` poses the whole body from a few effector targets (paper Fig. 5;
FaceIK from landmarks, Fig. 10) and draws the pose.

The config (``conf/map.yaml`` composed by Hydra, resolved to plain containers) holds
``rig``, ``paths``, ``regressor``, ``input``, ``targets``, ``out``, ``model``,
``model_cache`` and the ``map`` group (``conf/map/default.yaml``); ``config_dir`` is the
Hydra ``conf/`` folder, where retarget maps are found by name (``conf/retarget/<name>.yaml``).
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
import warnings
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from rigmap.animation.bvh import read_bvh
from rigmap.errors import RigmapError
from rigmap.map.clip import MAP_STEPS, MapSettings, map_clip
from rigmap.map.confidence import frame_confidence
from rigmap.map.joint_map import JointMap, JointMapError, MappedTargets
from rigmap.map.outputs import MappedClip, write_map_outputs
from rigmap.map.partial import JointSubset
from rigmap.map.partial_tracks import names_rig_joints, rig_joint_targets
from rigmap.map.skeleton_match import (
    Skeleton,
    check_frames,
    check_roles,
    match_bvh,
    match_skeleton,
)
from rigmap.map.subset_model import SubsetModel, obtain_subset_model
from rigmap.map.tracks import FrameWindow, read_tracks, tracks_from_motion
from rigmap.store import (
    Layout,
    json_ready,
    write_folder_atomic,
    write_json_atomic,
    write_text_atomic,
)

TRACK_SUFFIXES = (".parquet", ".csv", ".npz")
# Ours: the default of map.max_frames, the most frames one clip may map (about 55 minutes at
# 30 fps); a longer request is refused before it is read or mapped.
MAX_FRAMES = 100_000
# Ours: a clip of more frames than this shows a progress bar (on stderr) while it is mapped.
PROGRESS_FRAMES = 1_000
RETARGET_JOINTS = "retarget"  # a subset whose joints are the retarget map's
MATCH = "auto"  # map.retarget=auto: match the BVH skeleton even when the rig's default fits
Log = Callable[[str], None]


class MapConfigError(RigmapError, ValueError):
    """A map or pose config that names no input, an unknown subset, or an unusable value."""


def map_config(overrides: list[str], config_dir=None) -> dict[str, Any]:
    """``rigmap map``/``pose``'s config: ``conf/map.yaml`` with ``overrides``, the rig's
    ``_overrides_`` applied, resolved to the plain mapping the jobs below take."""
    from rigmap.app.config import compose_config
    from rigmap.app.objects import plain
    from rigmap.app.stage import stage_config

    return plain(stage_config(compose_config(overrides, config_dir, config_name="map")))


# --------------------------------------------------------------------------- map
def map_from_config(
    config: Mapping[str, Any], *, config_dir: str | os.PathLike, log: Log = print
) -> list[MappedClip]:
    """Map ``config["input"]`` onto ``config["rig"]``; one output folder per clip, written
    whole (:func:`write_map_outputs`, with the preview and a Blender rig's ``.blend``). A clip
    of more than :data:`PROGRESS_FRAMES` frames shows its steps on a progress bar (stderr)."""
    from rigmap.app import map_path_options as path_options
    from rigmap.rigs import load

    options = config["map"]
    window = frame_window(options)  # options first: a bad one is named before any file is read
    path_edit = path_options.path_edit_from_options(options)  # map.path: Fig. 7's edit
    corpus_clip = options.get("corpus_clip")
    sources = [] if corpus_clip else input_files(config.get("input"))
    preview = bool(options.get("preview", True))
    with load(rig_options(config)) as rig:
        out = Path(config.get("out") or Layout.user_output("map", rig.name))
        if corpus_clip:
            clips = [path_options.corpus_targets(config, rig, corpus_clip)]
            retarget = retarget_map(options, rig.name, config_dir)
        else:
            clips, retarget = read_clips(sources, rig, options, config_dir, out, log, window)
        subset = subset_for(options, rig, retarget, options.get("subset", "mocap"))
        settings = map_settings(options, rig.name)
        edited = {}
        if path_edit is not None:
            clips, edited = path_options.edit_clips(path_edit, rig, clips, settings.feet)
        model = _model(config, rig, subset, log)
        done = []
        for targets in _progress(clips, len(clips) > 1, "map"):
            with _step_bar(targets) as bar:
                result = map_clip(
                    rig,
                    targets,
                    model.mapping,
                    settings,
                    control_std=model.control_std,
                    hold_values=model.hold_values,
                    on_step=partial(_advance, bar),
                    planted=edited[targets.source].contacts if targets.source in edited else None,
                )
                confidence = frame_confidence(model.mapping, result.targets)
                _advance(bar, "confidence")
                folder = out / _stem(targets.source)
                extra = partial(_extra_outputs, rig, result, preview)
                if targets.source in edited:
                    clip = edited[targets.source]
                    extra = partial(path_options.with_path_outputs, extra, path_edit, clip, result)
                done.append(
                    write_map_outputs(folder, result, rig, confidence=confidence, extra=extra)
                )
                _advance(bar, "outputs")
            log(f"{done[-1].folder}: {_headline(done[-1].summary)}")
        return done


def _extra_outputs(rig, result, preview: bool, staging: Path) -> None:
    """The preview, and for a Blender rig (its animators work in a ``.blend``) a copy of its
    file with the mapping's reduced keys (``keys.json``) as a new action on its control bones."""
    from rigmap.rigs.blender.rig import BlenderRig

    if preview:
        from rigmap.map.preview import write_preview

        write_preview(staging, rig, result)
    if isinstance(rig, BlenderRig):
        from rigmap.map.blend_output import write_mapped_keys_blend

        write_mapped_keys_blend(rig, result.keys, result.fps, staging / "result.blend")


def input_files(value) -> list[Path]:
    """The files an ``input`` names: one BVH or tracks file, or every ``*.bvh`` of a folder."""
    if value in (None, ""):
        raise MapConfigError(
            "no input: pass input=<a .bvh file, a folder of them, or a joint "
            "tracks .parquet/.csv/.npz file>"
        )
    path = Path(value)
    if path.is_dir():
        files = sorted(path.glob("*.bvh"))
        if not files:
            raise MapConfigError(f"input folder {path} holds no .bvh files")
        return files
    if not path.is_file():
        raise FileNotFoundError(f"input {path} does not exist")
    if path.suffix.lower() not in (".bvh", *TRACK_SUFFIXES):
        raise MapConfigError(
            f"input {path}: unknown format {path.suffix!r}; use .bvh, a folder "
            "of .bvh files, .parquet, .csv or .npz"
        )
    return [path]


def retarget_map(options: Mapping, rig_name: str, config_dir) -> JointMap:
    """``map.retarget`` (a path, or a name in ``conf/retarget/``), else the rig's default."""
    name = options.get("retarget") or _rig_section(options, rig_name).get("retarget")
    if name == MATCH:
        raise MapConfigError(f"map.retarget={MATCH} matches BVH skeletons; it names no map")
    if not name:
        raise MapConfigError(
            f"no retarget map for rig {rig_name!r}: set map.retarget=<file or "
            f"name in {Path(config_dir) / 'retarget'}>"
        )
    path = Path(name)
    if path.suffix.lower() not in (".yaml", ".yml", ".json"):
        path = Path(config_dir) / "retarget" / f"{name}.yaml"
    retarget = JointMap.from_yaml(path)
    if retarget.rig != rig_name:
        raise MapConfigError(f"{path}: retarget map for rig {retarget.rig!r}, not {rig_name!r}")
    return retarget


def subset_for(options: Mapping, rig, retarget: JointMap | None, name: str) -> JointSubset:
    """The joint subset ``map.rigs.<rig>.subsets.<name>`` (``joints: retarget`` takes the
    retarget map's joints, and the map's name)."""
    subsets = _rig_section(options, rig.name).get("subsets") or {}
    if name not in subsets:
        raise MapConfigError(
            f"rig {rig.name!r} has no joint subset {name!r} in map.rigs."
            f"{rig.name}.subsets (has {sorted(subsets)}): add it under rigs: "
            "in map/default.yaml of the conf/ folder (for your own rig, a copy "
            "of conf/ given with --config-dir)"
        )
    spec = dict(subsets[name])
    if spec.get("joints") == RETARGET_JOINTS:
        if retarget is None:
            raise MapConfigError(f"joint subset {name!r} takes its joints from a retarget map")
        spec["joints"] = [j for j in rig.joint_names if j in retarget.joints]
        name = retarget.name
    return JointSubset.from_mapping(spec, name=name, rig=rig)


def map_settings(options: Mapping, rig_name: str) -> MapSettings:
    """:class:`MapSettings` from ``map.settings``, with the rig's own ``settings``
    (``map.rigs.<rig>.settings``: e.g. its IK/FK switches' names) over them, and the rig's
    ``feet``."""
    section = _rig_section(options, rig_name)
    settings = {**(options.get("settings") or {}), **(section.get("settings") or {})}
    if "hold" in settings:
        settings["hold"] = tuple(settings["hold"])
    feet = tuple(section.get("feet") or ())
    try:
        return MapSettings(feet=feet, **settings)
    except TypeError as error:
        raise MapConfigError(f"map.settings or map.rigs.{rig_name}.settings: {error}") from None


def read_clips(
    sources: list[Path],
    rig,
    options: Mapping,
    config_dir,
    out: Path,
    log: Log,
    window: FrameWindow | None = None,
) -> tuple[list[MappedTargets], JointMap | None]:
    """Every input as the rig's mapped joints, and the retarget map whose joints they are.

    ``map.retarget`` given: that map for every file. Otherwise the rig's default map for a
    file that has its source joints, and for a BVH without them (or with
    ``map.retarget=auto``) its skeleton matched to ``map.rigs.<rig>.roles``; the matched
    map is saved as ``<out>/<clip>.retarget.yaml`` (once per skeleton) and its path logged.
    Joint tracks that the default map does not fit and whose joints are all the rig's own
    (the quadruped's four paws) are taken as they are, with no map
    (:mod:`rigmap.map.partial_tracks`; the map returned is then None).
    ``window``: the frames mapped (default: ``map``'s, checked).
    """
    window = window or frame_window(options)
    chosen = options.get("retarget")
    fixed = retarget_map(options, rig.name, config_dir) if chosen and chosen != MATCH else None
    default = None
    if chosen is None and _rig_section(options, rig.name).get("retarget"):
        default = retarget_map(options, rig.name, config_dir)
    clips, maps, matched = [], [], {}
    for path in sources:
        motion = read_bvh(path) if path.suffix.lower() == ".bvh" else None
        if motion is not None:
            window.check_length(motion.n_frames, motion.fps, path)
            tracks = tracks_from_motion(motion, str(path))
        else:  # joint tracks; an npz is read (and checked) for the window's frames only
            unit, fps = options.get("unit", "cm"), options.get("source_fps")
            tracks = read_tracks(path, unit=unit, fps=fps, window=window)
            if path.suffix.lower() != ".npz":
                window.check_length(len(tracks.positions), tracks.fps, path)
        retarget = fixed or (default if default and _fits(default, tracks) else None)
        own = retarget is None and motion is None and names_rig_joints(tracks, rig)
        if retarget is None and motion is None and not own:  # the default map says what lacks
            retarget = default or retarget_map(options, rig.name, config_dir)
        was_matched = retarget is None and not own  # own: tracks of the rig's joints (feet…)
        if was_matched:
            retarget = _matched_map(path, motion, tracks, rig.name, options, out, matched, log)
        if motion is not None:
            tracks = _clean_frames(tracks, motion, log)
        maps.append(retarget)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # unused source joints: summarised below instead
            targets = rig_joint_targets(tracks, rig) if own else retarget.apply(rig, tracks)
        if path.suffix.lower() != ".npz":  # cut to the window (an npz was cut as it was read)
            cut = window.slice(targets.fps)
            if len(targets.positions[cut]) == 0:
                raise MapConfigError(
                    f"{path}: no frames left to map (the clip has {len(targets.positions)} "
                    f"frames; {window.describe()})"
                )
            targets = dataclasses.replace(
                targets, positions=targets.positions[cut], fps=targets.fps / cut.step
            )
        if was_matched:
            height = float(np.ptp(Skeleton.from_bvh(motion).rest @ retarget.axes_matrix[1]))
            log(
                f"{path}: scale {targets.scale:.4g} rig cm per source unit (from the bone "
                f"lengths): the source's rest height {height:.4g} units is "
                f"{height * targets.scale:.1f} cm on the rig"
            )
        clips.append(targets)
    driven = {tuple(t.joint_names) for t in clips}
    if len(driven) > 1:
        raise MapConfigError(
            f"the inputs' retarget maps drive different rig joints ({len(driven)} "
            "sets); map them in separate runs"
        )
    return clips, _subset_map(maps[0], default)


def _fits(retarget: JointMap, tracks) -> bool:
    return all(name in tracks.joint_names for name in retarget.joints.values())


def _clean_frames(tracks, motion, log: Log):
    """The tracks without an added T-pose at frame 0, glitch frames rebuilt (logged)."""
    skeleton = Skeleton.from_bvh(motion)
    frames = check_frames(motion.values, tracks.positions, skeleton.names, match_skeleton(skeleton))
    if not (frames.tpose_at_0 or frames.glitches):
        return tracks
    log(f"{tracks.source}: {frames.describe()}")
    try:
        return dataclasses.replace(tracks, positions=frames.apply(tracks.positions))
    except JointMapError as error:
        raise MapConfigError(f"{tracks.source}: {error}") from None


def _matched_map(
    path: Path, motion, tracks, rig_name: str, options: Mapping, out: Path, matched: dict, log: Log
) -> JointMap:
    """The BVH's skeleton matched for the rig, saved beside the output (once per skeleton)."""
    skeleton = Skeleton.from_bvh(motion)
    key = (skeleton.names, skeleton.rest.round(9).tobytes())
    if key not in matched:
        roles = check_roles(
            rig_name, _rig_section(options, rig_name).get("roles"), f"map.rigs.{rig_name}.roles"
        )
        result = match_bvh(
            motion,
            tracks.positions,
            rig_name,
            roles,
            source=str(path),
            draft=out / f"{path.stem}.retarget.draft.yaml",
        )
        saved = write_text_atomic(out / f"{path.stem}.retarget.yaml", result.text)
        retarget = JointMap.from_yaml(saved)
        log(f"{path}: {result.describe()}; retarget map used: {saved}")
        matched[key] = retarget
    return matched[key]


def _subset_map(retarget: JointMap | None, default: JointMap | None) -> JointMap | None:
    """The map that names the joint subset: a matched map driving the default map's rig
    joints shares its name (and so its cached model); None for tracks of the rig's joints."""
    if retarget is not None and default is not None and set(retarget.joints) == set(default.joints):
        return dataclasses.replace(retarget, name=default.name)
    return retarget


def frame_window(options: Mapping) -> FrameWindow:
    """``map.first_frame``, ``map.frames``, ``map.fps`` and ``map.max_frames``, checked (and
    ``map.source_fps``); ``map.frames`` over the cap is refused before any file is read."""
    cap = options.get("max_frames", MAX_FRAMES)
    if cap is None:
        raise MapConfigError(f"map.max_frames=None: expected an integer >= 1 (ours: {MAX_FRAMES})")
    cap = _option({"max_frames": cap}, "max_frames", 1, "an integer >= 1 (the most frames mapped)")
    first = _option(options, "first_frame", 0, "an integer >= 0 (a source frame)")
    count = _option(options, "frames", 1, "an integer >= 1 (frames to map) or null (all)")
    if count is not None and count > cap:
        raise MapConfigError(
            f"map.frames={count}: expected an integer in 1..{cap} (map.max_frames) or null (all)"
        )
    fps = _option(options, "fps", 0.0, "a number > 0 (frames per second) or null (the source's)")
    _option(options, "source_fps", 0.0, "a number > 0 (the tracks' frames per second) or null")
    return FrameWindow(0 if first is None else first, count, fps, max_frames=cap)


def _option(options: Mapping, key: str, bound, expected: str):
    """``map.<key>``: ``None``, or an int ``>= bound`` (int bound) or a finite number
    ``> bound`` (float bound); ``MapConfigError`` naming it otherwise."""
    value = options.get(key)
    if value is None:
        return None
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if isinstance(bound, int):
        good = number and float(value).is_integer() and value >= bound
    else:
        good = number and np.isfinite(value) and value > bound
    if not good:
        raise MapConfigError(f"map.{key}={value!r}: expected {expected}")
    return int(value) if isinstance(bound, int) else float(value)


def _model(config: Mapping, rig, subset: JointSubset, log: Log) -> SubsetModel:
    layout = Layout.from_paths(config.get("paths"))
    return obtain_subset_model(
        rig,
        subset,
        layout,
        config["regressor"],
        folder=config.get("model"),
        cache=config.get("model_cache"),
        log=log,
    )


def rig_options(config: Mapping) -> dict:
    return {k: v for k, v in dict(config["rig"]).items() if k != "corpus"}


def _rig_section(options: Mapping, rig_name: str) -> Mapping:
    return (options.get("rigs") or {}).get(rig_name) or {}


def _stem(source: str) -> str:
    return Path(source).stem


def _headline(summary: dict) -> str:
    return (
        f"{summary['frames']} frames, joint error {summary['joint_error_rms_cm']:.2f} cm RMS "
        f"({summary['joint_error_rms_percent_of_height']:.2f} % of height), "
        f"{summary['keys']} keys"
    )


def _progress(items, show: bool, what: str):
    from tqdm.auto import tqdm

    return tqdm(items, desc=what, unit="clip", disable=not show)


# What :func:`map_from_config` reports of a clip after :func:`map_clip`'s own steps.
ONE_CLIP_STEPS = (*MAP_STEPS, "confidence", "outputs")


def _step_bar(targets: MappedTargets):
    """A bar over :data:`ONE_CLIP_STEPS` on stderr, shown for a long clip only."""
    from tqdm.auto import tqdm

    frames = len(targets.positions)
    return tqdm(
        total=len(ONE_CLIP_STEPS),
        desc=f"map {_stem(targets.source)} ({frames} frames)",
        unit="step",
        file=sys.stderr,
        disable=frames <= PROGRESS_FRAMES,
    )


def _advance(bar, name: str) -> None:
    """One step of ``bar`` done; the bar names it."""
    bar.set_postfix_str(name, refresh=False)
    bar.update(1)


# --------------------------------------------------------------------------- pose
def pose_from_config(config: Mapping[str, Any], *, log: Log = print) -> Path:
    """Pose ``config["rig"]`` from the effector targets file ``config["targets"]``; writes
    ``<out>/`` with ``controls.json`` (used controls per pose, and the distance to the
    targets) and ``pose_<k>.png`` per pose (the targets drawn over the pose)."""
    from rigmap.map.effectors import pose_from_effectors, read_effector_targets
    from rigmap.rigs import load

    options = config["map"]
    targets_file = config.get("targets")
    if not targets_file:
        raise MapConfigError("no targets: pass targets=<effector targets .json>")
    with load(rig_options(config)) as rig:
        subset = pose_subset(options, rig)
        targets = read_effector_targets(targets_file, subset.joints)  # before a long fit
        model, settings = _model(config, rig, subset, log), map_settings(options, rig.name)
        mode = options.get("pose_mode", "drag")
        if mode == "drag":
            controls, error, seconds = _drag(rig, model, targets, settings, options.get("drag"))
        elif mode == "batch":
            # a few effectors are reached exactly by plain Eq. 13 (prior_weight 0); the pull
            # toward the guess is for the many joints of a clip (MapSettings' docstring)
            plain = dataclasses.replace(settings, feet=(), prior_weight=0.0)
            controls, error, seconds = pose_from_effectors(
                rig,
                model.mapping,
                targets,
                plain,
                control_std=model.control_std,
                hold_values=model.hold_values,
            )
        else:
            raise MapConfigError(f"map.pose_mode: expected 'drag' or 'batch', got {mode!r}")
        out = Path(
            config.get("out") or Layout.user_output("pose", rig.name) / Path(targets_file).stem
        )
        write_folder_atomic(
            out,
            lambda staging: _write_poses(staging, rig, subset, controls, targets, error, seconds),
        )
        log(
            f"{out}: {len(controls)} pose(s), distance to the targets "
            f"{float(error.max()):.3f} cm at most"
        )
        return out


def pose_subset(options: Mapping[str, Any], rig) -> JointSubset:
    """The effectors posing ``rig``: ``map.pose_subset``, else the rig's ``pose_subset``,
    else ``effectors``."""
    name = options.get("pose_subset") or _rig_section(options, rig.name).get("pose_subset")
    return subset_for(options, rig, None, name or "effectors")


def posing_parts(config: Mapping[str, Any], rig, log: Log = print):
    """``(subset, model, settings)`` of posing ``rig`` from effectors: the joint subset
    (:func:`pose_subset`), its mapping (fitted once, then cached), the refinement settings."""
    options = config["map"]
    subset = pose_subset(options, rig)
    return subset, _model(config, rig, subset, log), map_settings(options, rig.name)


def interactive_poser(rig, model, settings, options):
    """:class:`InteractivePoser` with ``map.drag``'s options (checked)."""
    from rigmap.map.interactive_pose import InteractivePoser

    options = dict(options or {})
    unknown = sorted(set(options) - {"steps", "carry_jacobian"})
    if unknown:
        raise MapConfigError(f"map.drag: unknown keys {unknown}; known: steps, carry_jacobian")
    try:
        return InteractivePoser(
            rig,
            model.mapping,
            control_std=model.control_std,
            hold_values=model.hold_values,
            hold=settings.hold,
            damping=settings.damping,
            **options,
        )
    except (TypeError, ValueError) as error:
        raise MapConfigError(f"map.drag: {error}") from None


def _drag(rig, model, targets, settings, options) -> tuple[np.ndarray, np.ndarray, dict]:
    """The poses of ``targets`` in order, as :class:`InteractivePoser` follows a drag."""
    poser = interactive_poser(rig, model, settings, options)
    started = time.perf_counter()
    results = [poser(frame) for frame in targets]
    seconds = {
        "pose_s": time.perf_counter() - started,
        "rig_evaluations": float(sum(r.rig_evaluations for r in results)),
    }
    controls = np.array([r.controls for r in results])
    return controls, np.array([r.distance_cm for r in results]), seconds


def _write_poses(staging: Path, rig, subset, controls, targets, error, seconds) -> None:
    from rigmap.map.preview import render_pose

    used = rig.controls.used_indices
    poses = [
        {
            "used_controls": dict(zip(rig.used_controls, row[used].tolist(), strict=True)),
            "target_distance_rms_cm": float(e),
        }
        for row, e in zip(controls, error, strict=True)
    ]
    write_json_atomic(
        staging / "controls.json",
        json_ready(
            {"rig": rig.name, "effectors": list(subset.joints), "poses": poses, "seconds": seconds}
        ),
    )
    for k in range(len(controls)):
        render_pose(
            rig,
            controls[k],
            targets[k],
            subset,
            staging / f"pose_{k}.png",
            title=f"{rig.name} posed from {len(subset.joints)} targets ({error[k]:.2f} cm RMS)",
        )
