"""``rigmap edits learn`` and ``rigmap edits apply --model``: an artist's pairs to files.

:func:`learn_folder` reads and checks every pair before it fits or writes anything, then
writes the model as arrays + JSON (``edit.npz`` and ``edit.json``,
:func:`rigmap.edits.propagation.save_model`: nothing pickled) and ``learned.json`` (the
pairs, their frames, what was repaired, the fit) into the folder. :func:`apply_folder`
reads and checks every input clip and propagates the edit to each before it writes any
file, then writes per clip ``<name>.bvh`` (the source's hierarchy, a fixed frame rate)
and ``<name>.npz`` (the edited track's values, as the stages' output), and
``applied.json`` (per clip: frames in and out, frame rate, resampling, repairs).
"""

from __future__ import annotations

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
    read_clip,
    read_pair,
)
from rigmap.edits.propagation import EditModel, load_model, save_model
from rigmap.edits.study import weights_from
from rigmap.store import atomic_file, json_ready, write_json_atomic, write_text_atomic

MODEL_STEM = "edit"


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
    """Read and check every pair, fit, then write the model and ``learned.json``."""
    specs = [(Path(s).resolve(), Path(e).resolve(), f) for s, e, f in specs]
    pairs = [read_pair(s, e, f, glitch) for s, e, f in specs]
    rows = [
        {
            "source": str(s),
            "edited": str(e),
            "frames": [p.source.start, p.source.start + p.source.track.n_frames],
            "example_frames": int(p.examples.sum()),
            "notes": [*p.source.notes, *p.edited.notes, *_left_out(p)],
        }
        for (s, e, _), p in zip(specs, pairs, strict=True)
    ]
    summary = {"pairs": rows, "glitch": glitch, "fixes": []}
    fit_and_write(pairs, [], Path(out), settings, summary)
    return Path(out)


def _left_out(pair) -> list[str]:
    """A line saying which frames of the pair are not examples (repaired glitches)."""
    frames = np.flatnonzero(~pair.examples) + pair.source.start
    if not len(frames):
        return []
    return [
        f"frames {frames.tolist()} (from 0) left out of the examples: repaired, or "
        "right after a repaired frame"
    ]


def new_model(motion, settings: dict) -> EditModel:
    """An unfitted model for a skeleton, as ``conf/edits/default.yaml`` sets it up."""
    return EditModel(
        feature_joints(motion),
        weights_from(settings["weights"]),
        residual=bool(settings["residual"]),
        max_iterations=int(settings["max_iterations"]),
        input_scale=str(settings.get("input_scale", "global")),
    )


def fit_and_write(
    pairs, extra: list[tuple], out: Path, settings: dict, summary: dict, files: dict | None = None
):
    """Fit on the pairs (and ``extra`` examples), then write ``files`` (path → text), the
    model and ``learned.json`` (``summary`` plus what the fit found); returns the model."""
    model = new_model(pairs[0].source.motion, settings)
    started = time.perf_counter()
    learn_pairs(pairs, model, extra)
    summary = {
        **summary,
        "joints": list(pairs[0].source.motion.joint_names),
        "fps": pairs[0].source.track.fps,
        "fit_s": time.perf_counter() - started,
        "kinematic_length_scale": model.kinematic_gp_.length_scale_,
        "acceleration_length_scale": model.acceleration_gp_.length_scale_,
    }
    for path, text in (files or {}).items():
        write_text_atomic(path, text)
    save_model(model, out / f"{MODEL_STEM}.npz")
    write_json_atomic(out / "learned.json", json_ready(summary))
    return model


def apply_folder(model_dir, inputs, out, fps: float | None = None, glitch: str = "repair"):
    """Propagate the learned edit to a BVH file or a folder's; returns the files written."""
    model_dir = Path(model_dir)
    model = load_model(model_dir / f"{MODEL_STEM}.npz")
    files = bvh_files(inputs)
    stems = [f.stem for f in files]
    if len(set(stems)) != len(stems):
        raise PairError(f"{inputs}: two inputs share a name; their outputs would collide")
    results = []
    for path in files:  # everything computed and checked before anything is written
        clip = read_clip(path, None, glitch)
        track = apply_clip(model, clip, fps)
        results.append((path, clip, track, bvh_text(clip_motion(track, clip))))
    out, written, rows = Path(out), [], []
    for path, clip, track, text in results:
        written.append(write_text_atomic(out / f"{path.stem}.bvh", text))
        with atomic_file(out / f"{path.stem}.npz", suffix=".npz") as temporary:
            np.savez(
                temporary,
                values=track.values,
                channels=np.array(track.channels),
                fps=np.array(track.fps),
                start=np.array(track.start),
            )
        written.append(out / f"{path.stem}.npz")
        rows.append(
            {
                "input": str(path),
                "bvh": str(out / f"{path.stem}.bvh"),
                "frames_in": clip.track.n_frames,
                "frames_out": track.n_frames,
                "fps_in": clip.track.fps,
                "fps_out": track.fps,
                "resampled": track.n_frames != clip.track.n_frames
                or abs(track.fps - clip.track.fps) > 1e-9,
                "notes": list(clip.notes),
            }
        )
    summary = {"model": str(model_dir), "clips": rows}
    written.append(write_json_atomic(out / "applied.json", json_ready(summary)))
    return written, summary
