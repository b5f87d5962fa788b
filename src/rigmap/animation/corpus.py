"""The animator corpus on disk: every frame of every clip, in rig space, as parquet.

A corpus is a table with columns ``clip``, ``frame`` and one column per used
control, one row per played frame (keys and the frames interpolated between them,
§6.1). What a reader needs to trust the numbers travels inside the file, in the
parquet schema metadata under ``rigmap``: the rig, frame rate, seed, split,
control order, and per-clip frame ranges and key counts. Files are written through
:mod:`rigmap.store` (atomically, deterministically): the same clips give byte-identical files.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.animation.clip import Clip, check_known_controls
from rigmap.animation.keyframes import KeyframeError
from rigmap.errors import RigmapError
from rigmap.store import read_table_file, write_table_file

CORPUS_FORMAT = "rigmap.corpus/1"
METADATA_KEY = b"rigmap"
KEY_COLUMNS: tuple[str, str] = ("clip", "frame")


class CorpusError(RigmapError, ValueError):
    """A corpus that cannot be built, or a file that is not a valid corpus."""


class SoftRangeWarning(UserWarning):
    """A key outside the soft range an animator normally works in (allowed, but unusual)."""


@dataclass
class Corpus:
    """A corpus table and the metadata that describes it."""

    table: pd.DataFrame
    metadata: dict = field(default_factory=dict)

    # --- building ----------------------------------------------------------
    @classmethod
    def from_clips(
        cls,
        clips: Sequence[Clip],
        control_names: Sequence[str],
        defaults: Sequence[float] | np.ndarray,
        *,
        rig: str,
        split: str,
        seed: int | None = None,
        lower: Sequence[float] | np.ndarray | None = None,
        upper: Sequence[float] | np.ndarray | None = None,
        extra: Mapping | None = None,
    ) -> Corpus:
        """Validate ``clips`` against the rig's controls and play every frame of each.

        ``control_names`` are the columns (the rig's used controls); ``defaults``
        fill controls a clip has no curve on; ``lower``/``upper`` are the soft range
        (keys outside only warn). ``extra`` is stored in the metadata as it is
        (must be JSON-serialisable).
        """
        control_names = list(control_names)
        validate_clips(clips, control_names, lower, upper)
        table = corpus_table(clips, control_names, defaults)
        metadata = {
            "format": CORPUS_FORMAT,
            "rig": rig,
            "split": split,
            "seed": None if seed is None else int(seed),
            "fps": clips[0].fps,
            "controls": control_names,
            "defaults": [float(d) for d in np.asarray(defaults, dtype=np.float64)],
            "clips": [_clip_summary(clip) for clip in clips],
            "frame_count": len(table),
            "key_count": sum(clip.key_count for clip in clips),
            "keyed_frame_count": sum(len(clip.keyed_frames) for clip in clips),
            "extra": dict(extra or {}),
        }
        return cls(table, metadata)

    # --- views -------------------------------------------------------------
    @property
    def controls(self) -> list[str]:
        return list(self.metadata["controls"])

    @property
    def clip_names(self) -> list[str]:
        return [c["name"] for c in self.metadata["clips"]]

    @property
    def fps(self) -> int:
        return int(self.metadata["fps"])

    @property
    def rig(self) -> str:
        return self.metadata["rig"]

    @property
    def split(self) -> str:
        return self.metadata["split"]

    @property
    def key_count(self) -> int:
        return int(self.metadata["key_count"])

    def values(self) -> np.ndarray:
        """``(N, C)`` control values in ``controls`` order."""
        return self.table[self.controls].to_numpy(dtype=np.float64)

    def clip_table(self, name: str) -> pd.DataFrame:
        """The rows of one clip."""
        if name not in self.clip_names:
            raise KeyError(f"no clip named {name!r} in the corpus; clips: {self.clip_names}")
        return self.table[self.table["clip"] == name].reset_index(drop=True)

    # --- files -------------------------------------------------------------
    def write(self, path: str | os.PathLike) -> Path:
        """Write atomically and deterministically; returns the path written."""
        return write_corpus(path, self.table, self.metadata)

    @classmethod
    def read(
        cls,
        path: str | os.PathLike,
        *,
        rig: str | None = None,
        control_names: Sequence[str] | None = None,
        split: str | None = None,
    ) -> Corpus:
        """Read and validate a corpus file; optionally insist on its rig, controls, split."""
        table, metadata = read_corpus(path, rig=rig, control_names=control_names, split=split)
        return cls(table, metadata)


# --- validation -----------------------------------------------------------------
def validate_clips(
    clips: Sequence[Clip],
    control_names: Sequence[str],
    lower: Sequence[float] | np.ndarray | None = None,
    upper: Sequence[float] | np.ndarray | None = None,
) -> None:
    """Errors for what cannot be played; a ``SoftRangeWarning`` per out-of-range curve.

    NaN keys, duplicate key frames and empty clips are already refused when a
    ``Clip`` is built (naming clip and control); here come the checks that need the
    rig: unknown control names, a mixed frame rate, repeated clip names, an empty
    corpus, and keys outside the soft ``(lower, upper)`` range.
    """
    clips = list(clips)
    control_names = list(control_names)
    if not clips:
        raise CorpusError("the corpus is empty: no clips were given")
    if not control_names:
        raise CorpusError("no control names given: a corpus needs at least one control column")
    names = [c.name for c in clips]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise CorpusError(f"clip names must be unique in a corpus; repeated: {repeated}")
    for clip in clips:
        if not isinstance(clip, Clip):
            raise CorpusError(f"expected Clip objects, got {type(clip).__name__}: {clip!r}")
        if clip.fps != clips[0].fps:
            raise KeyframeError(
                f"{clip.fps} fps, but clip {clips[0].name!r} is {clips[0].fps} fps; "
                "one corpus has one frame rate",
                clip=clip.name,
            )
        check_known_controls(clip, control_names)
    if lower is None and upper is None:
        return
    column = {name: i for i, name in enumerate(control_names)}
    lower = _range_bound(lower, -np.inf, len(control_names), "lower")
    upper = _range_bound(upper, np.inf, len(control_names), "upper")
    for clip in clips:
        for control, curve in clip.curves.items():
            lo, hi = lower[column[control]], upper[column[control]]
            outside = (curve.values < lo) | (curve.values > hi)
            if not outside.any():
                continue
            excess = np.maximum(lo - curve.values, curve.values - hi)
            worst = int(np.argmax(excess))
            warnings.warn(
                f"clip {clip.name!r}, control {control!r}: {int(outside.sum())} key(s) outside "
                f"the soft range [{lo:g}, {hi:g}]; worst value {curve.values[worst]:g} at "
                f"frame {curve.frames[worst]:g}",
                SoftRangeWarning,
                stacklevel=2,
            )


def corpus_table(
    clips: Sequence[Clip],
    control_names: Sequence[str],
    defaults: Sequence[float] | np.ndarray,
) -> pd.DataFrame:
    """Every whole frame of every clip: ``clip``, ``frame``, one column per control."""
    control_names = list(control_names)
    clashing = [name for name in control_names if name in KEY_COLUMNS]
    if clashing:
        raise CorpusError(f"control names {clashing} clash with the corpus columns {KEY_COLUMNS}")
    parts = []
    for clip in clips:
        values = clip.evaluate(control_names, defaults)
        part = pd.DataFrame(values, columns=control_names)
        part.insert(0, "frame", clip.frames)
        part.insert(0, "clip", clip.name)
        parts.append(part)
    if not parts:
        raise CorpusError("the corpus is empty: no clips were given")
    table = pd.concat(parts, ignore_index=True)
    table["clip"] = table["clip"].astype(str)
    table["frame"] = table["frame"].astype(np.int64)
    return table


def _clip_summary(clip: Clip) -> dict:
    return {
        "name": clip.name,
        "start": clip.start,
        "end": clip.end,
        "frames": clip.n_frames,
        "key_count": clip.key_count,
        "keyed_frames": len(clip.keyed_frames),
        "curves": len(clip.curves),
        "description": clip.description,
    }


def _range_bound(bound, fill: float, n: int, which: str) -> np.ndarray:
    if bound is None:
        return np.full(n, fill)
    bound = np.asarray(bound, dtype=np.float64)
    if bound.shape != (n,):
        raise CorpusError(f"soft range {which} must have shape ({n},), got {bound.shape}")
    return bound


# --- files ----------------------------------------------------------------------
def write_corpus(path: str | os.PathLike, table: pd.DataFrame, metadata: Mapping) -> Path:
    """Write ``table`` with ``metadata`` (JSON in the schema) to ``path``, atomically.

    Output is deterministic: no timestamps are stored, dictionary keys are sorted,
    and the same table and metadata give the same bytes (:func:`rigmap.store.write_table_file`).
    """
    _check_table(table, metadata, source="table to write")
    return write_table_file(path, table, METADATA_KEY, metadata, error=CorpusError, what="corpus")


def read_corpus(
    path: str | os.PathLike,
    *,
    rig: str | None = None,
    control_names: Sequence[str] | None = None,
    split: str | None = None,
) -> tuple[pd.DataFrame, dict]:
    """Read a corpus file and check it against its own metadata (and the caller's needs)."""
    path = Path(path)
    table, metadata = read_table_file(path, METADATA_KEY, error=CorpusError, what="corpus")
    if metadata.get("format") != CORPUS_FORMAT:
        raise CorpusError(
            f"{path}: corpus format {metadata.get('format')!r}, expected {CORPUS_FORMAT!r}"
        )
    for name, wanted in (("rig", rig), ("split", split)):
        if wanted is not None and metadata.get(name) != wanted:
            raise CorpusError(
                f"{path}: corpus is for {name} {metadata.get(name)!r}, expected {wanted!r}"
            )
    if control_names is not None and list(control_names) != metadata["controls"]:
        have, want = metadata["controls"], list(control_names)
        missing = [c for c in want if c not in have]
        unexpected = [c for c in have if c not in want]
        detail = (
            f"missing {missing[:10]}, unexpected {unexpected[:10]}"
            if missing or unexpected
            else "same names in a different order"
        )
        raise CorpusError(f"{path}: corpus controls differ from the rig's: {detail}")
    _check_table(table, metadata, source=str(path))
    return table, metadata


def _check_table(table: pd.DataFrame, metadata: Mapping, source: str) -> None:
    """The table holds exactly what the metadata says, with finite values."""
    for key in ("controls", "clips", "fps", "rig", "split"):
        if key not in metadata:
            raise CorpusError(f"{source}: corpus metadata lacks {key!r}")
    controls = list(metadata["controls"])
    expected = [*KEY_COLUMNS, *controls]
    if list(table.columns) != expected:
        missing = [c for c in expected if c not in table.columns]
        unexpected = [c for c in table.columns if c not in expected]
        raise CorpusError(
            f"{source}: columns do not match the metadata: missing {missing[:10]}, "
            f"unexpected {unexpected[:10]} (expected 'clip', 'frame', then the controls)"
        )
    if len(table) == 0:
        raise CorpusError(f"{source}: the corpus is empty (no rows)")
    if not pd.api.types.is_integer_dtype(table["frame"]):
        raise CorpusError(f"{source}: column 'frame' must be integers, got {table['frame'].dtype}")
    values = table[controls]
    non_float = [c for c in controls if not pd.api.types.is_float_dtype(values[c])]
    if non_float:
        raise CorpusError(f"{source}: control columns must be floats; not: {non_float[:10]}")
    finite = np.isfinite(values.to_numpy(dtype=np.float64))
    if not finite.all():
        row, col = np.argwhere(~finite)[0]
        raise CorpusError(
            f"{source}: clip {table['clip'].iloc[row]!r}, control {controls[col]!r}: value "
            f"{values.iat[row, col]} at frame {table['frame'].iloc[row]}; values must be finite"
        )
    clip, row = misplaced_clip(table, metadata["clips"])
    if clip is not None:
        raise CorpusError(
            f"{source}: clip {clip['name']!r}: expected frames {clip['start']}..{clip['end']}"
            f" ({clip['frames']} rows) starting at row {row}; the table does not hold them there"
        )
    if row != len(table):
        raise CorpusError(
            f"{source}: {len(table) - row} rows after the last clip in the metadata "
            f"({metadata['clips'][-1]['name'] if metadata['clips'] else 'none'})"
        )


def misplaced_clip(table: pd.DataFrame, clips: Sequence[Mapping]) -> tuple[Mapping | None, int]:
    """Walk ``clips`` (the metadata's summaries) down the ``clip`` and ``frame`` columns:
    the first clip whose rows are not where the summaries put them and the row it should
    start at, else ``(None, rows the clips cover)``. Corpus and poses files lay out their
    clips alike, so both check them here; each words its own error."""
    clip_column = table["clip"].to_numpy()
    frames = table["frame"].to_numpy()
    row = 0
    for clip in clips:
        count = clip["frames"]
        rows = slice(row, row + count)
        if (
            row + count > len(table)
            or not (clip_column[rows] == clip["name"]).all()
            or not np.array_equal(frames[rows], np.arange(clip["start"], clip["end"] + 1))
        ):
            return clip, row
        row += count
    return None, row
