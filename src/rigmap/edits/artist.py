"""``rigmap edits learn`` and ``rigmap edits apply --model``: an artist's pairs to files.

Two modes. Skeleton mode: example pairs of BVH files, BVH clips out
(:mod:`rigmap.edits.pairs`). Rig mode: controls parquets of a built-in rig, as ``rigmap
map`` writes them, in and out (:mod:`rigmap.edits.rig_pairs`).

:func:`learn_folder` (skeleton) and :func:`learn_rig_folder` (rig) read and check every
pair before they fit or write anything, then write the model as arrays + JSON
(``edit.npz`` and ``edit.json``, :func:`rigmap.edits.propagation.save_model`: nothing
pickled) and ``learned.json`` (the mode — and in rig mode the rig and the frame rate the
parquets were read at — the pairs, their frames, what was repaired, the fit) into the
folder. :func:`apply_folder` reads the mode from ``learned.json`` (a folder without one,
or without a mode, is skeleton mode: the folders written before rig mode), refuses input
of the other mode, reads and checks every input clip and propagates the edit to each
before it writes any file. Then per clip: skeleton mode ``<name>.bvh`` (the source's
hierarchy, a fixed frame rate), rig mode ``<name>.parquet`` (``frame`` and every used
control) and a ``<name>.blend`` action when the rig has a Blender form (or, in
``applied.json``, why none was written); both ``<name>.npz`` (the edited track's values,
as the stages' output) and ``applied.json`` (per clip: frames in and out, frame rate,
resampling, repairs).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from rigmap.animation.bvh_write import bvh_text
from rigmap.edits.pairs import (
    PairError,
    apply_clip,
    bvh_files,
    clip_motion,
    feature_joints,
    learn_pairs,
    propagate,
    read_clip,
    read_pair,
)
from rigmap.edits.propagation import EditModel, FeatureJoints, load_model, save_model
from rigmap.edits.representation import TargetTrack
from rigmap.edits.rig_mode import rig_controls
from rigmap.edits.rig_pairs import (
    RigMode,
    controls_inputs,
    controls_table,
    learn_rig_pairs,
    read_controls,
    read_rig_pair,
    write_controls,
)
from rigmap.edits.study import weights_from
from rigmap.store import (
    atomic_file,
    json_ready,
    write_bytes_atomic,
    write_json_atomic,
    write_text_atomic,
)

MODEL_STEM = "edit"
MODES = ("skeleton", "rig")


def parse_frames(text: str | None) -> tuple[int, int] | None:
    """``START:STOP`` (frames from 0, STOP excluded) or ``all``/None for the whole clip."""
    if text is None or text == "all":
        return None
    start, sep, stop = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return int(start), int(stop)
    except ValueError:
        raise PairError(f"--frames {text!r}: expected START:STOP (frames from 0) or all") from None


def pair_specs(sources, edited, frames) -> list[tuple]:
    """``(source, edited, frames)`` per pair from the repeated options, checked."""
    sources, edited, frames = list(sources or []), list(edited or []), list(frames or [])
    if not sources or len(sources) != len(edited):
        raise PairError(
            f"give --source and --edited once per pair: {len(sources)} --source, "
            f"{len(edited)} --edited"
        )
    if frames and len(frames) != len(sources):
        raise PairError(
            f"--frames: give it once per pair or not at all ({len(frames)} for "
            f"{len(sources)} pairs)"
        )
    ranges = [parse_frames(f) for f in frames] or [None] * len(sources)
    return list(zip(sources, edited, ranges, strict=True))


def learn_folder(specs: list[tuple], out, settings: dict, glitch: str = "repair") -> Path:
    """Skeleton mode: read and check every BVH pair, fit, then write the model and
    ``learned.json``."""
    check_mode_files([p for s, e, _ in specs for p in (s, e)], "skeleton")
    specs = [(Path(s).resolve(), Path(e).resolve(), f) for s, e, f in specs]
    pairs = [read_pair(s, e, f, glitch) for s, e, f in specs]
    rows = [
        _pair_row(s, e, p, [p.source.start, p.source.start + p.source.track.n_frames], _left_out(p))
        for (s, e, _), p in zip(specs, pairs, strict=True)
    ]
    summary = {"mode": "skeleton", "pairs": rows, "glitch": glitch, "fixes": []}
    fit_and_write(pairs, [], Path(out), settings, summary)
    return Path(out)


def learn_rig_folder(specs: list[tuple], out, settings: dict, mode: RigMode) -> Path:
    """Rig mode: read and check every pair of controls parquets (``--frames`` are their
    ``frame`` column's numbers), fit, then write the model and ``learned.json`` with the
    rig and the frame rate (:meth:`RigMode.summary`)."""
    check_mode_files([p for s, e, _ in specs for p in (s, e)], "rig")
    specs = [(Path(s).resolve(), Path(e).resolve(), f) for s, e, f in specs]
    pairs = [read_rig_pair(s, e, f, mode) for s, e, f in specs]
    rows = [
        _pair_row(s, e, p, list(p.source.frames)) for (s, e, _), p in zip(specs, pairs, strict=True)
    ]
    summary = {**mode.summary(), "pairs": rows, "fixes": []}
    fit_and_write(pairs, [], Path(out), settings, summary, subject=mode.subject)
    return Path(out)


def _pair_row(source, edited, pair, frames: list[int], left_out=()) -> dict:
    """A pair as ``learned.json`` lists it, in either mode."""
    return {
        "source": str(source),
        "edited": str(edited),
        "frames": frames,
        "example_frames": int(pair.examples.sum()),
        "notes": [*pair.source.notes, *pair.edited.notes, *left_out],
    }


def check_mode_files(paths, mode: str, model_dir=None) -> None:
    """A controls parquet is rig mode's, anything else (a BVH) skeleton mode's: a file of
    the other mode is a one-line error naming it (and ``model_dir``, the model whose mode
    it is not, when a model decides the mode)."""
    for path in paths:
        parquet = Path(path).suffix.lower() == ".parquet"
        if mode == "skeleton" and parquet:
            hint = (
                ": name its rig with --rig (e.g. --rig biped), or give BVH files"
                if model_dir is None
                else f", but {model_dir} is a skeleton-mode edit (learned on BVH pairs): give "
                "BVH files, or learn the edit on parquets with --rig"
            )
            raise PairError(f"{path}: a controls parquet (rig mode){hint}")
        if mode == "rig" and not parquet:
            hint = (
                "rig mode (--rig) takes controls parquets (BVH pairs go without --rig)"
                if model_dir is None
                else f"{model_dir} is a rig-mode edit (learned with --rig): give controls parquets"
            )
            raise PairError(f"{path}: not a .parquet; {hint}")


def _left_out(pair) -> list[str]:
    """A line saying which frames of the pair are not examples (repaired glitches)."""
    frames = np.flatnonzero(~pair.examples) + pair.source.start
    if not len(frames):
        return []
    return [
        f"frames {frames.tolist()} (from 0) left out of the examples: repaired, or "
        "right after a repaired frame"
    ]


def new_model(joints: FeatureJoints, settings: dict) -> EditModel:
    """An unfitted model on the feature joints, as ``conf/edits/default.yaml`` sets it up."""
    return EditModel(
        joints,
        weights_from(settings["weights"]),
        residual=bool(settings["residual"]),
        max_iterations=int(settings["max_iterations"]),
        input_scale=str(settings.get("input_scale", "global")),
    )


def fit_and_write(
    pairs,
    extra: list[tuple],
    out: Path,
    settings: dict,
    summary: dict,
    files: dict | None = None,
    subject=None,
):
    """Fit on the pairs (and ``extra`` examples), then write ``files`` (path → text or
    bytes), the model and ``learned.json`` (``summary`` plus what the fit found); returns
    the model. ``subject``: rig mode's (:class:`RigMode`'s), None for BVH pairs."""
    if subject is None:
        model = new_model(feature_joints(pairs[0].source.motion), settings)
        joint_names = pairs[0].source.motion.joint_names
    else:
        model = new_model(subject.joints, settings)
        joint_names = subject.joint_names
    started = time.perf_counter()
    if subject is None:
        learn_pairs(pairs, model, extra)
    else:
        learn_rig_pairs(pairs, model, subject, extra)
    summary = {
        **summary,
        "joints": list(joint_names),
        "fps": pairs[0].source.track.fps,
        "fit_s": time.perf_counter() - started,
        "kinematic_length_scale": model.kinematic_gp_.length_scale_,
        "acceleration_length_scale": model.acceleration_gp_.length_scale_,
    }
    for path, content in (files or {}).items():
        if isinstance(content, bytes):
            write_bytes_atomic(path, content)
        else:
            write_text_atomic(path, content)
    save_model(model, out / f"{MODEL_STEM}.npz")
    write_json_atomic(out / "learned.json", json_ready(summary))
    return model


def read_learned(model_dir) -> tuple[dict, str]:
    """A model folder's ``learned.json`` (empty when there is none) and its mode."""
    path = Path(model_dir) / "learned.json"
    learned = json.loads(path.read_text()) if path.is_file() else {}
    mode = learned.get("mode", "skeleton")
    if mode not in MODES:
        raise PairError(f"{path}: mode {mode!r} is not one of {MODES}")
    return learned, mode


def apply_folder(model_dir, inputs, out, fps: float | None = None, glitch: str = "repair"):
    """Propagate the learned edit to a file or a folder's (the model's mode decides which:
    BVH files, or controls parquets); returns the files written and the summary."""
    model_dir = Path(model_dir)
    model = load_model(model_dir / f"{MODEL_STEM}.npz")
    learned, mode = read_learned(model_dir)
    if mode == "rig":
        rig_mode = RigMode.from_learned(learned, str(model_dir / "learned.json"))
        return apply_rig_folder(model, model_dir, rig_mode, inputs, out, fps)
    if Path(inputs).is_file():
        check_mode_files([inputs], "skeleton", model_dir)
    files = bvh_files(inputs)
    _check_names([f.stem for f in files], inputs)
    results = []
    for path in files:  # everything computed and checked before anything is written
        clip = read_clip(path, None, glitch)
        track = apply_clip(model, clip, fps)
        results.append((path, clip, track, bvh_text(clip_motion(track, clip))))
    out, written, rows = Path(out), [], []
    for path, clip, track, text in results:
        written.append(write_text_atomic(out / f"{path.stem}.bvh", text))
        written.append(write_track(out / f"{path.stem}.npz", track))
        rows.append(
            {
                "input": str(path),
                "bvh": str(out / f"{path.stem}.bvh"),
                **_frames_row(clip.track, track),
                "notes": list(clip.notes),
            }
        )
    summary = {"model": str(model_dir), "mode": "skeleton", "clips": rows}
    written.append(write_json_atomic(out / "applied.json", json_ready(summary)))
    return written, summary


def _check_names(names: list[str], inputs) -> None:
    if len(set(names)) != len(names):
        raise PairError(f"{inputs}: two inputs share a name; their outputs would collide")


def _frames_row(given, result) -> dict:
    """Frames and rates in and out of one applied clip."""
    return {
        "frames_in": given.n_frames,
        "frames_out": result.n_frames,
        "fps_in": given.fps,
        "fps_out": result.fps,
        "resampled": result.n_frames != given.n_frames or abs(result.fps - given.fps) > 1e-9,
    }


def write_track(path: Path, track) -> Path:
    """The edited track's values, channels, rate and start as ``.npz`` (no pickles)."""
    with atomic_file(path, suffix=".npz") as temporary:
        np.savez(
            temporary,
            values=track.values,
            channels=np.array(track.channels),
            fps=np.array(track.fps),
            start=np.array(track.start),
        )
    return Path(path)


def read_track(npz: Path) -> TargetTrack:
    """The edited track :func:`write_track` wrote (exact values)."""
    with np.load(npz, allow_pickle=False) as stored:
        return TargetTrack(
            tuple(str(c) for c in stored["channels"]),
            stored["values"],
            float(stored["fps"]),
            tuple(float(v) for v in stored["start"]),
            source=str(npz),
        )


def apply_rig_folder(model: EditModel, model_dir: Path, mode: RigMode, inputs, out, fps=None):
    """Rig mode's :func:`apply_folder`: controls parquets in (read at the model's frame
    rate), ``<name>.parquet`` (``frame`` and every used control, at ``fps`` or the model's
    rate), ``<name>.npz`` and a ``<name>.blend`` action (or why not) out."""
    files = controls_inputs(inputs)
    _check_names([name for name, _ in files], inputs)
    writer, no_blend = _blend_writer(mode.rig)
    results = []
    for name, path in files:  # everything computed and checked before anything is written
        clip = read_controls(path, mode)
        track = propagate(model, mode.subject.source(clip.track), fps)
        table = controls_table(rig_controls(track, mode.channels), mode.used, clip.first_frame)
        results.append((name, path, clip, track, table))
    out, written, rows = Path(out), [], []
    for name, path, clip, track, table in results:
        written.append(write_controls(out / f"{name}.parquet", table))
        written.append(write_track(out / f"{name}.npz", track))
        blend = None
        if writer is not None:
            blend = out / f"{name}.blend"
            with atomic_file(blend, suffix=".blend") as temporary:
                writer(mode.rig, table, temporary, fps=track.fps, action_name=f"{name}_edit")
            written.append(blend)
        rows.append(
            {
                "input": str(path),
                "parquet": str(out / f"{name}.parquet"),
                "blend": None if blend is None else str(blend),
                **({"no_blend": no_blend} if blend is None else {}),
                **_frames_row(clip.track, track),
                "notes": list(clip.notes),
            }
        )
    summary = {"model": str(model_dir), "mode": "rig", "rig": mode.rig.name, "clips": rows}
    written.append(write_json_atomic(out / "applied.json", json_ready(summary)))
    return written, summary


def _blend_writer(rig):
    """The rig's .blend writer and None, or None and why the rig has none."""
    from rigmap.rigs.blender.lookup import NotBlenderRigError
    from rigmap.rigs.blender.writers import blend_writer

    try:
        return blend_writer(rig), None
    except NotBlenderRigError as error:
        return None, f"no .blend written: {error}"
