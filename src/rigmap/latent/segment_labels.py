"""Labels a user writes: a YAML of label → segments of Live Link Face takes (issue #41, 3).

A capture library comes unlabelled; the user marks what each stretch shows::

    takes: ../../../../shared/face   # folder of the CSVs, relative to this file
    fps: 30                          # rate the segments are resampled to (default 30, ours)
    labels:
      talking:
        - {take: S07-001, from_s: 12.0, to_s: 20.5}   # seconds from the take's first row
        - {take: S07-001, frames: [600, 900]}         # or frames at ``fps``, end excluded
        - {take: S88-001}                             # or the whole take

``takes`` may also name one file whose takes the segments cut
(:mod:`rigmap.latent.take_files`): a ``.blend`` (a take per action) or a controls table
(``.csv``/``.parquet``, a take per value of its ``take`` column); ``fps`` is then the
file's frame rate.

:func:`read_labels` checks the file's shape (read with ``yaml.safe_load``: data only);
:func:`labelled_takes` reads each take once and cuts its segments into
:class:`~rigmap.latent.library.Take` s, a segment that leaves its take or holds no
tracked frame being an error naming the label. Lost tracking inside a segment splits it
(each tracked stretch one take of the dynamics prior).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from rigmap.latent.library import Take
from rigmap.latent.live_link import MIN_SEGMENT_FRAMES, RESAMPLE_FPS, LiveLinkError, read_take

TAKE_NAME = re.compile(r"^[A-Za-z0-9_.-]+$")  # a file stem in the takes folder, no path
END_SLACK_S = 1e-6  # ours: a segment may end on the take's last row, rounding aside


class LabelFileError(LiveLinkError):
    """A label YAML that cannot be used: its shape, or a segment against its take."""


@dataclass(frozen=True)
class LabelSegment:
    label: str
    take: str
    from_s: float
    to_s: float


@dataclass(frozen=True)
class LabelFile:
    path: Path
    source: Path  # the folder of Live Link CSVs, or one .blend / controls table
    fps: float
    segments: tuple[LabelSegment, ...]

    @property
    def labels(self) -> list[str]:
        return list(dict.fromkeys(s.label for s in self.segments))


def _segment(path: Path, label: str, k: int, entry, fps: float) -> LabelSegment:
    where = f"{path}: label {label!r}, segment {k + 1}"
    if not isinstance(entry, dict) or "take" not in entry:
        raise LabelFileError(f"{where}: expected {{take: NAME, from_s: S, to_s: S}}")
    extra = set(entry) - {"take", "from_s", "to_s", "frames"}
    if extra:
        raise LabelFileError(f"{where}: unknown keys {sorted(extra)}")
    take = str(entry["take"])
    if set(entry) == {"take"}:  # the whole take
        return LabelSegment(label, take, 0.0, math.inf)
    if "frames" in entry:
        frames = entry["frames"]
        if set(entry) & {"from_s", "to_s"} or not (
            isinstance(frames, list) and len(frames) == 2 and all(type(f) is int for f in frames)
        ):
            raise LabelFileError(f"{where}: frames must be [first, end] (whole numbers) alone")
        start, end = frames[0] / fps, frames[1] / fps
    else:
        try:
            start, end = float(entry["from_s"]), float(entry["to_s"])
        except (KeyError, TypeError, ValueError):
            raise LabelFileError(f"{where}: from_s and to_s must both be seconds") from None
    if not (np.isfinite(start) and np.isfinite(end) and 0.0 <= start < end):
        raise LabelFileError(f"{where}: the segment {start:g}-{end:g} s is empty or negative")
    return LabelSegment(label, take, start, end)


def read_labels(path) -> LabelFile:
    """A label YAML, checked for shape (errors name the file and the label)."""
    path = Path(path)
    if not path.is_file():
        raise LabelFileError(f"{path}: no such label file")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise LabelFileError(f"{path}: not YAML ({str(error).splitlines()[0]})") from None
    if not isinstance(data, dict) or not isinstance(data.get("labels"), dict):
        raise LabelFileError(f"{path}: expected a mapping with `labels: {{label: [segments]}}`")
    extra = set(data) - {"takes", "fps", "labels"}
    if extra:
        raise LabelFileError(f"{path}: unknown keys {sorted(extra)} (takes, fps, labels)")
    fps = data.get("fps", RESAMPLE_FPS)
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not 0 < fps <= 240:
        raise LabelFileError(f"{path}: fps must be a number in (0, 240], got {fps!r}")
    source = (path.parent / str(data.get("takes", "."))).resolve()
    segments = []
    for label, entries in data["labels"].items():
        if not isinstance(entries, list) or not entries:
            raise LabelFileError(f"{path}: label {label!r} needs a list of segments")
        segments += [_segment(path, str(label), k, e, float(fps)) for k, e in enumerate(entries)]
    return LabelFile(path, source, float(fps), tuple(segments))


def labelled_takes(labels: LabelFile, *, names=None) -> list[Take]:
    """Every segment's tracked stretches as takes ``"<label> <take> <from>-<to>[/k]"``
    with the values of columns ``names`` (default: every column of the take)."""
    cache, takes = {}, []
    for seg in labels.segments:
        where = f"{labels.path}: label {seg.label!r}"
        if not TAKE_NAME.match(seg.take):
            raise LabelFileError(f"{where}: take {seg.take!r} is not a file stem (no folders)")
        if seg.take not in cache:
            csv = labels.source / f"{seg.take}.csv"
            if not csv.is_file():
                raise LabelFileError(f"{where}: no take {seg.take!r} ({csv} is missing)")
            take = read_take(csv)
            cache[seg.take] = (take, take.segments(labels.fps))
        take, stretches = cache[seg.take]
        length = take.span_s[1] - take.span_s[0]
        if math.isfinite(seg.to_s) and seg.to_s > length + END_SLACK_S:
            raise LabelFileError(
                f"{where}: segment {seg.from_s:g}-{seg.to_s:g} s is outside take "
                f"{seg.take!r} ({length:.2f} s long)"
            )
        pieces = _cut(take, stretches, seg, names)
        if not pieces:
            raise LabelFileError(
                f"{where}: segment {seg.from_s:g}-{seg.to_s:g} s of {seg.take!r} holds no "
                "tracked frames (tracking was lost there)"
            )
        base = segment_name(seg)
        for k, values in enumerate(pieces):
            takes.append(Take(seg.label, base if len(pieces) == 1 else f"{base}/{k}", values))
    return takes


def segment_name(seg: LabelSegment) -> str:
    """``"<label> <take> <from>-<to>"`` (seconds), or ``"<label> <take>"`` for a whole take."""
    if math.isinf(seg.to_s):
        return f"{seg.label} {seg.take}"
    return f"{seg.label} {seg.take} {seg.from_s:.2f}-{seg.to_s:.2f}"


def _cut(take, stretches, seg: LabelSegment, names) -> list[np.ndarray]:
    """The parts of the resampled stretches inside the segment (times from the first row)."""
    columns = take.columns if names is None else tuple(names)
    unknown = [name for name in columns if name not in take.columns]
    if unknown:
        raise LabelFileError(f"{take.path}: no column {unknown[0]!r} for label {seg.label!r}")
    index = [take.columns.index(name) for name in columns]
    pieces = []
    for stretch in stretches:
        t = stretch.start_s - take.span_s[0] + np.arange(len(stretch.values)) / stretch.fps
        inside = (t >= seg.from_s - END_SLACK_S) & (t < seg.to_s - END_SLACK_S)
        if inside.sum() >= MIN_SEGMENT_FRAMES:
            pieces.append(stretch.values[inside][:, index])
    return pieces
