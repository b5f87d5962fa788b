"""``rigmap edits fix``: the artist's correction of a frame range joins the examples (§3).

"If the artist does not like any part of the animation, (s)he can fix the estimate. The
system incorporates these fixes into the training data and produces a new estimate" (§3,
Fig 2). A fix is a BVH of the corrected frames (the source clip's skeleton, one frame per
corrected frame) and the range ``START:STOP`` of the source file they replace. The model
folder keeps a copy of every fix (``fixes/fix_<k>.bvh``) and lists them in
``learned.json``, so a refit re-reads the original pairs and every fix so far: the source
clip with the fixed frames put in is an example on those frames only (the features see
the whole clip; :meth:`EditModel.fit`'s frame masks). After the refit the frames of
highest configuration variance on that clip, not fixed yet, are suggested next, as
segments (:func:`rigmap.edits.incremental.suggest_segments`, the study's rule).

A rig-mode model (learned on controls parquets, :mod:`rigmap.edits.rig_pairs`) takes its
fix as a controls parquet too: the ``frame`` column numbers the frames it replaces (it
must be ``START..STOP-1`` of ``--frames``), every used control of the rig a column,
checked as the pairs are; the folder keeps ``fixes/fix_<k>.parquet``. A file of the
other mode is refused with one line.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from rigmap.animation import read_bvh
from rigmap.animation.bvh_write import bvh_text
from rigmap.edits.artist import check_mode_files, fit_and_write, read_learned
from rigmap.edits.incremental import Suggestion, suggest_segments
from rigmap.edits.pairs import PairError, read_clip, read_pair, rebuilt_frames, without_glitches
from rigmap.edits.rig_mode import rig_targets
from rigmap.edits.rig_pairs import (
    RigMode,
    controls_table,
    read_control_values,
    read_controls,
    read_rig_pair,
)
from rigmap.edits.skeleton_mode import Skeleton, skeleton_targets


def fix_examples(fixes: list[dict], glitch: str, folder: Path) -> list[tuple]:
    """``(source, edited track, mask)`` per fixed source clip, every fix of it put in (in
    order: a later fix of the same frames wins; its ``left_out`` frames, glitches, are no
    examples); a fix's values are its ``values`` (one being handed in, glitches rebuilt)
    or its file's, relative to ``folder`` (the model's) unless absolute."""
    by_source: dict[str, list[dict]] = {}
    for fix in fixes:
        by_source.setdefault(fix["source"], []).append(fix)
    examples = []
    for source, items in by_source.items():
        clip = read_clip(source, None, glitch)
        values = clip.motion.values.copy()
        mask = np.zeros(clip.track.n_frames, dtype=bool)
        for fix in items:
            start, stop = (int(v) - clip.start for v in fix["frames"])
            given = fix.get("values")
            values[start:stop] = (
                read_bvh(Path(folder) / fix["file"]).values if given is None else given
            )
            mask[start:stop] = True
            mask[[int(f) - clip.start for f in fix.get("left_out", ())]] = False
        edited = skeleton_targets(replace(clip.motion, values=values))
        examples.append((clip.source(), edited, mask & ~clip.bad))
    return examples


def check_fix(source, fixed, frames: tuple[int, int], glitch: str):
    """The source clip, the fixed frames' motion and its capture glitches (a mask; rebuilt
    from their neighbours, or refused with ``glitch="refuse"``) with a note, checked: the
    same skeleton, the range inside the clip's motion, one fixed frame per frame of the
    range."""
    clip = read_clip(source, None, glitch)
    motion = read_bvh(fixed)
    Skeleton.of(clip.motion).check_same(Skeleton.of(motion), str(fixed))
    start, stop = frames
    first, last = clip.start, clip.start + clip.track.n_frames
    if not first <= start < stop <= last:
        raise PairError(
            f"--frames {start}:{stop} is outside the motion of {source} (frames {first}:{last})"
        )
    if motion.n_frames != stop - start:
        raise PairError(
            f"{fixed}: {motion.n_frames} frames for the {stop - start} frames of --frames "
            f"{start}:{stop}"
        )
    if abs(motion.frame_time - clip.motion.frame_time) > 1e-9:
        raise PairError(
            f"{fixed}: frame time {motion.frame_time:g} s, {source}'s is "
            f"{clip.motion.frame_time:g} s"
        )
    values, bad, notes = without_glitches(motion, str(fixed), glitch)
    # a frame the source never captured (a glitch there) holds no correction either: the
    # fix's value is rebuilt from its neighbours, as the source's was
    inherited = clip.bad[start - clip.start : stop - clip.start] & ~bad
    if inherited.any():
        bad = bad | inherited
        values = rebuilt_frames(motion, values, bad)
        which = [start + int(k) for k in np.flatnonzero(inherited)]
        notes.append(
            f"{fixed}: frames {which} of {source} are capture glitches there, so the fix's "
            "values for them were rebuilt from its neighbouring frames"
        )
    return clip, replace(motion, values=values), bad, notes


def fix_folder(
    model_dir, source, fixed, frames, settings: dict, count: int = 3, segment: int = 12
) -> tuple[list[Suggestion], list[str]]:
    """Add the fix, refit on the pairs and every fix, write the model; the suggestions and
    what was done to the fix (glitches rebuilt, also in ``learned.json``)."""
    model_dir = Path(model_dir)
    learned, mode = read_learned(model_dir)
    if not learned:
        raise PairError(f"{model_dir}: no learned.json; not a folder of rigmap edits learn")
    if mode == "rig":
        return fix_rig_folder(model_dir, learned, source, fixed, frames, settings, count, segment)
    check_mode_files([source, fixed], "skeleton", model_dir)
    glitch = learned.get("glitch", "repair")
    source = Path(source).resolve()
    clip, motion, bad, notes = check_fix(source, fixed, frames, glitch)
    pairs = [
        read_pair(p["source"], p["edited"], tuple(p["frames"]), glitch) for p in learned["pairs"]
    ]
    fixes = list(learned.get("fixes") or [])
    name = f"fixes/fix_{len(fixes)}.bvh"  # in the model folder, which may move
    entry = {"source": str(source), "frames": [int(v) for v in frames], "file": name}
    if bad.any():  # a glitch in the fix: rebuilt in the stored copy, never an example frame
        entry |= {"left_out": [frames[0] + int(k) for k in np.flatnonzero(bad)], "notes": notes}
    given = {**entry, "values": motion.values}
    examples = fix_examples([*fixes, given], glitch, model_dir)
    summary = {k: v for k, v in learned.items() if k in ("pairs", "glitch")}
    summary["fixes"] = [*fixes, entry]
    # the fix's copy is written with the model, after the fit: a failed fit writes nothing
    files = {model_dir / name: bvh_text(motion)}
    model = fit_and_write(pairs, examples, model_dir, settings, summary, files)
    variance = model.predict(clip.source())[0].variance
    mask = next(m for s, _, m in examples if s.track.source == clip.track.source)
    picks = suggest_segments([variance], {0: mask}, count, segment)
    return [replace(p, start=p.start + clip.start, stop=p.stop + clip.start) for p in picks], notes


def check_rig_fix(source, fixed, frames: tuple[int, int], mode: RigMode):
    """The source clip and the fix's used controls ``(STOP - START, U)``, checked: the
    range inside the clip, the fix's ``frame`` column the range's numbers."""
    clip = read_controls(source, mode)
    start, stop = frames
    first, last = clip.frames
    if not first <= start < stop <= last:
        raise PairError(
            f"--frames {start}:{stop} is outside the frames of {source} ({first}:{last})"
        )
    values, fix_first, _ = read_control_values(fixed, mode.rig, min_frames=1)
    if (fix_first, fix_first + len(values)) != (start, stop):
        raise PairError(
            f"{fixed}: frames {fix_first}:{fix_first + len(values)}, but --frames is "
            f"{start}:{stop} (a fix's frame column numbers the frames of --source it replaces)"
        )
    return clip, values


def rig_fix_examples(fixes: list[dict], mode: RigMode, folder: Path) -> list[tuple]:
    """Rig mode's :func:`fix_examples`: ``(source, edited track, mask)`` per fixed source
    clip, every fix of it put in (a later fix of the same frames wins); a fix's controls
    are its ``values`` or its file's, relative to ``folder`` unless absolute."""
    by_source: dict[str, list[dict]] = {}
    for fix in fixes:
        by_source.setdefault(fix["source"], []).append(fix)
    examples = []
    for source, items in by_source.items():
        clip = read_controls(source, mode)
        controls = clip.controls.copy()
        mask = np.zeros(len(controls), dtype=bool)
        for fix in items:
            start, stop = (int(v) - clip.first_frame for v in fix["frames"])
            given = fix.get("values")
            if given is None:
                given = read_control_values(Path(folder) / fix["file"], mode.rig, min_frames=1)[0]
            controls[start:stop] = given
            mask[start:stop] = True
        edited = rig_targets(controls, mode.channels, mode.fps, source=f"{source} (fixed)")
        examples.append((mode.subject.source(clip.track), edited, mask))
    return examples


def fix_rig_folder(
    model_dir: Path, learned: dict, source, fixed, frames, settings: dict, count, segment
) -> tuple[list[Suggestion], list[str]]:
    """Rig mode's :func:`fix_folder` (controls parquets; the model's rig and frame rate)."""
    rig_mode = RigMode.from_learned(learned, str(model_dir / "learned.json"))
    check_mode_files([source, fixed], "rig", model_dir)
    source = Path(source).resolve()
    clip, values = check_rig_fix(source, fixed, frames, rig_mode)
    pairs = [
        read_rig_pair(p["source"], p["edited"], tuple(p["frames"]), rig_mode)
        for p in learned["pairs"]
    ]
    fixes = list(learned.get("fixes") or [])
    name = f"fixes/fix_{len(fixes)}.parquet"  # in the model folder, which may move
    entry = {"source": str(source), "frames": [int(v) for v in frames], "file": name}
    examples = rig_fix_examples([*fixes, {**entry, "values": values}], rig_mode, model_dir)
    summary = {**rig_mode.summary(), "pairs": learned["pairs"], "fixes": [*fixes, entry]}
    # the fix's copy is written with the model, after the fit: a failed fit writes nothing
    table = controls_table(values, rig_mode.used, frames[0])
    files = {model_dir / name: table.to_parquet(None, index=False)}
    model = fit_and_write(
        pairs, examples, model_dir, settings, summary, files, subject=rig_mode.subject
    )
    variance = model.predict(rig_mode.subject.source(clip.track))[0].variance
    mask = next(m for s, _, m in examples if s.track.source == clip.track.source)
    picks = suggest_segments([variance], {0: mask}, count, segment)
    first = clip.first_frame
    return [replace(p, start=p.start + first, stop=p.stop + first) for p in picks], []
