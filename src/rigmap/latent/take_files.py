"""Labelled takes from a user's own files: what ``latent.takes`` (``rigmap synth fit
--takes FILE``) names (issue #41, item 1).

- a **label YAML** (:mod:`rigmap.latent.segment_labels`): segments of takes, labelled. Its
  ``takes`` is a folder of Live Link Face CSVs, or one of the two files below, whose takes
  the segments cut (by frames or seconds at the file's ``fps``, or whole);
- a **controls table** (``.csv`` or ``.parquet``): one column per used control of the rig,
  named as the rig names them (an ARKit face's are ARKit's blendshape names), and optional
  ``frame`` (every frame, in order), ``take`` and ``label`` columns. Without a label YAML
  the ``label`` column labels it: each run of rows with one take and one label is a take;
- a **.blend**: every action a take on the rig's controls, read as ``rigmap learn`` reads
  them (:func:`rigmap.animation.blend_corpus.import_blend_corpus`: keys as stored, curves
  it cannot model baked from Blender's own values), labelled by ``label_pattern`` on the
  action's name (default: the name's leading letters, ``happy_02`` → ``happy``).

Files are data only: tables through pandas' readers, the .blend in a Blender worker with
its scripts off. Every error names the file and the row, column, take or label.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np

from rigmap.latent.errors import LatentInputError
from rigmap.latent.library import Take
from rigmap.latent.live_link import live_link_columns
from rigmap.latent.segment_labels import (
    END_SLACK_S,
    LabelFile,
    labelled_takes,
    read_labels,
    segment_name,
)

TABLE_SUFFIXES = (".csv", ".parquet")
LABEL_SUFFIXES = (".yaml", ".yml")
FRAME_COLUMN, TAKE_COLUMN, LABEL_COLUMN = "frame", "take", "label"
#: ours: an action's label is its leading letters ("happy_02", "Happy.001" → happy, Happy)
DEFAULT_LABEL_PATTERN = r"^[A-Za-z]+"
MIN_TAKE_FRAMES = 3  # ours: a take needs velocity and acceleration (the dynamics prior)


class TakeFileError(LatentInputError):
    """A takes file that cannot be read as labelled takes (file and row or label named)."""


def read_labelled_takes(path, rig, *, fps: float, label_pattern: str | None = None) -> list[Take]:
    """``path``'s labelled takes on ``rig``'s used controls (columns in the rig's order)."""
    path = Path(path).expanduser()
    suffix = path.suffix.lower()
    if not path.exists():
        raise TakeFileError(f"{path}: no such takes file")
    if suffix in LABEL_SUFFIXES:
        return _label_file_takes(path, rig, fps=fps)
    if label_pattern is not None and suffix != ".blend":
        raise TakeFileError(f"{path}: label_pattern labels a .blend's actions, not a {suffix}")
    if suffix in TABLE_SUFFIXES:
        return table_takes(path, rig.used_controls)
    if suffix == ".blend":
        named = blend_takes(path, rig, fps=fps)
        labels = labels_by_pattern(list(named), label_pattern or DEFAULT_LABEL_PATTERN, path)
        return [Take(labels[name], name, values) for name, values in named.items()]
    raise TakeFileError(
        f"{path}: takes must be a label YAML, a controls table ({', '.join(TABLE_SUFFIXES)}) "
        f"or a .blend, got {suffix or 'no suffix'}"
    )


def _label_file_takes(path: Path, rig, *, fps: float) -> list[Take]:
    file = read_labels(path)
    if abs(file.fps - float(fps)) > 1e-9:
        raise TakeFileError(
            f"{file.path}: its takes are at {file.fps:g} fps, but the latent stages run "
            f"{rig.name!r} at {float(fps):g} fps (latent.fps or latent.<rig>_fps)"
        )
    if file.source.is_dir():  # Live Link Face CSVs: columns by ARKit's names
        return labelled_takes(file, names=live_link_columns(rig.used_controls))
    suffix = file.source.suffix.lower()
    if suffix in TABLE_SUFFIXES:
        named = {}
        for take in table_takes(file.source, rig.used_controls, labelled=False):
            named[take.name] = take.values
    elif suffix == ".blend":
        named = blend_takes(file.source, rig, fps=fps)
    else:
        raise TakeFileError(
            f"{file.path}: takes must be a folder of Live Link CSVs, a controls table or a "
            f".blend, got {file.source}"
        )
    return cut_segments(file, named)


def cut_segments(file: LabelFile, named: dict[str, np.ndarray]) -> list[Take]:
    """The label file's segments cut from takes ``named`` (frames at ``file.fps``)."""
    takes = []
    for seg in file.segments:
        where = f"{file.path}: label {seg.label!r}"
        if seg.take not in named:
            raise TakeFileError(
                f"{where}: no take {seg.take!r} in {file.source.name}; takes: {list(named)[:8]}"
            )
        values = named[seg.take]
        length_s = len(values) / file.fps
        if math.isfinite(seg.to_s) and seg.to_s > length_s + END_SLACK_S:
            raise TakeFileError(
                f"{where}: segment {seg.from_s:g}-{seg.to_s:g} s is outside take "
                f"{seg.take!r} ({len(values)} frames, {length_s:.2f} s at {file.fps:g} fps)"
            )
        first = round(seg.from_s * file.fps)
        end = len(values) if math.isinf(seg.to_s) else round(seg.to_s * file.fps)
        piece = values[first:end]
        if len(piece) < MIN_TAKE_FRAMES:
            raise TakeFileError(
                f"{where}: segment {segment_name(seg)!r} holds {len(piece)} frames; a take "
                f"needs at least {MIN_TAKE_FRAMES}"
            )
        takes.append(Take(seg.label, segment_name(seg), piece))
    return takes


def table_takes(path, controls, *, labelled: bool = True) -> list[Take]:
    """A controls table's takes: runs of rows with one ``take`` (and, if ``labelled``, one
    ``label``), values in the order of ``controls``; ``labelled=False`` refuses a label
    column (the label YAML labels the table) and returns one unlabelled take per take."""
    import pandas as pd

    path = Path(path)
    try:
        table = pd.read_parquet(path) if path.suffix.lower() == ".parquet" else pd.read_csv(path)
    except Exception as error:  # pandas and pyarrow raise many kinds on a bad file
        raise TakeFileError(f"{path}: not a readable table ({type(error).__name__})") from None
    columns = [str(c) for c in table.columns]
    controls = list(controls)
    meta = {FRAME_COLUMN, TAKE_COLUMN, LABEL_COLUMN}
    unknown = [c for c in columns if c not in meta and c not in controls]
    if unknown:
        raise TakeFileError(
            f"{path}: column {unknown[0]!r} is not a used control of the rig "
            f"({len(unknown)} unknown; used controls look like {controls[:4]})"
        )
    missing = [c for c in controls if c not in columns]
    if missing:
        raise TakeFileError(
            f"{path}: no column for used controls {missing[:6]} ({len(missing)} missing)"
        )
    if labelled and LABEL_COLUMN not in columns:
        raise TakeFileError(
            f"{path}: no {LABEL_COLUMN!r} column; add one or label the table in a label YAML "
            f"(takes: {path.name})"
        )
    if not labelled and LABEL_COLUMN in columns:
        raise TakeFileError(
            f"{path}: has a {LABEL_COLUMN!r} column, but a label YAML labels it; keep one"
        )
    if table.empty:
        raise TakeFileError(f"{path}: the table has no rows")
    values = _numbers(table, controls, path)
    takes_of = table[TAKE_COLUMN].astype(str) if TAKE_COLUMN in columns else None
    names = takes_of.to_numpy() if takes_of is not None else np.full(len(table), path.stem)
    labels = table[LABEL_COLUMN] if labelled else None
    if labels is not None and labels.isna().any():
        row = int(np.flatnonzero(labels.isna().to_numpy())[0])
        raise TakeFileError(f"{path}: row {row + 1} has no label")
    labels = None if labels is None else labels.astype(str).to_numpy()
    keys = np.array(
        [str(n) if labels is None else f"{n}\0{labels[k]}" for k, n in enumerate(names)],
        dtype=object,
    )
    frames = _frames(table, path) if FRAME_COLUMN in columns else None
    takes, seen = [], set()
    for start, end in _runs(keys):
        name = str(names[start])
        if frames is not None:
            _check_every_frame(frames[start:end], start, name, path)
        label = None if labels is None else str(labels[start])
        if labels is None and name in seen:
            raise TakeFileError(
                f"{path}: take {name!r} is split (again at row {start + 1}); keep its rows together"
            )
        seen.add(name)
        first = int(frames[start]) if frames is not None else start
        title = name if labels is None else f"{label} {name} {first}-{first + end - start}"
        if end - start < MIN_TAKE_FRAMES:
            raise TakeFileError(
                f"{path}: take {title!r} (rows {start + 1}-{end}) has {end - start} frames; "
                f"a take needs at least {MIN_TAKE_FRAMES}"
            )
        takes.append(Take(label, title, values[start:end]))
    return takes


def _numbers(table, controls, path) -> np.ndarray:
    import pandas as pd

    block = table[controls]
    numeric = block.apply(pd.to_numeric, errors="coerce")
    bad = numeric.isna().to_numpy() | ~np.isfinite(numeric.to_numpy(dtype=np.float64))
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise TakeFileError(
            f"{path}: row {row + 1}, column {controls[column]!r} is not a finite number "
            f"({block.iat[row, column]!r})"
        )
    return numeric.to_numpy(dtype=np.float64)


def _frames(table, path) -> np.ndarray:
    frames = table[FRAME_COLUMN].to_numpy()
    try:
        as_float = frames.astype(np.float64)
    except (TypeError, ValueError):
        raise TakeFileError(f"{path}: column {FRAME_COLUMN!r} must hold whole numbers") from None
    if not (np.isfinite(as_float).all() and (as_float == np.round(as_float)).all()):
        raise TakeFileError(f"{path}: column {FRAME_COLUMN!r} must hold whole numbers")
    return as_float.astype(np.int64)


def _check_every_frame(frames: np.ndarray, offset: int, name: str, path: Path) -> None:
    steps = np.diff(frames)
    if (steps != 1).any():
        k = int(np.flatnonzero(steps != 1)[0])
        raise TakeFileError(
            f"{path}: row {offset + k + 2}: frame {frames[k + 1]} follows {frames[k]} in take "
            f"{name!r}; a take needs one row per frame, in order"
        )


def _runs(keys: np.ndarray) -> list[tuple[int, int]]:
    """``(start, end)`` of each run of equal consecutive keys."""
    cuts = np.flatnonzero(keys[1:] != keys[:-1]) + 1
    edges = [0, *cuts.tolist(), len(keys)]
    return list(itertools.pairwise(edges))


def labels_by_pattern(names: list[str], pattern: str, path: Path) -> dict[str, str]:
    """Each name's label: the pattern's ``label`` group, else its first group, else the whole
    match (``re.search``); a name the pattern does not match is an error naming it."""
    try:
        compiled = re.compile(pattern)
    except re.error as error:
        raise TakeFileError(f"label_pattern {pattern!r} is not a regex: {error}") from None
    labels = {}
    for name in names:
        found = compiled.search(name)
        if found is None:
            raise TakeFileError(
                f"{path}: action {name!r} does not match label_pattern {pattern!r}; rename it "
                "or label the actions in a label YAML"
            )
        group = "label" if "label" in compiled.groupindex else (1 if compiled.groups else 0)
        label = found.group(group)
        if not label:
            raise TakeFileError(f"{path}: action {name!r} gets an empty label from {pattern!r}")
        labels[name] = label
    return labels


def blend_takes(path, rig, *, fps: float) -> dict[str, np.ndarray]:
    """Every action of ``path`` sampled on its whole frames, on ``rig``'s used controls
    (controls an action does not key sit at their rest values). ``rig`` is a Blender rig
    (``rig=blend_file``): its armature options read the file."""
    from rigmap.animation.blend_corpus import SESSION_KEYS, import_blend_corpus

    options = getattr(rig, "session_options", None)
    if options is None:
        raise TakeFileError(
            f"{path}: a .blend's actions are takes of a Blender rig; run with rig=blend_file "
            f"rig.path=<the rig's .blend> (got rig {rig.name!r})"
        )
    keys = [k for k in SESSION_KEYS if options.get(k) is not None and k not in ("used",)]
    corpus = import_blend_corpus(
        path, **{k: options[k] for k in keys}, check_determinism=False, split=False
    )
    if abs(corpus.fps - float(fps)) > 1e-9:
        raise TakeFileError(
            f"{path}: its actions play at {corpus.fps} fps, but the latent stages run "
            f"{rig.name!r} at {float(fps):g} fps (set latent.fps={corpus.fps})"
        )
    used = rig.used_controls
    stray = [c for c in corpus.used if c not in used]
    if stray:
        raise TakeFileError(
            f"{path}: its actions key {stray[:6]}, which rig {rig.name!r} does not use "
            "(build the rig from the same file: rig.path=)"
        )
    defaults = rig.default_controls(1)[0][rig.controls.used_indices]
    return {clip.name: clip.evaluate(used, defaults) for clip in corpus.clips}
