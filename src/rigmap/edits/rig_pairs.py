"""An artist's own edits in rig mode: controls parquets of a built-in rig in and out.

A controls parquet is what ``rigmap map`` writes (``controls.parquet``): a ``frame``
column and one column per control of the rig; a clip's ``rigmap map`` output folder is an
input by that file (:func:`controls_inputs`). Rig mode edits the rig's used controls
(:mod:`rigmap.edits.rig_mode`: the root's ``root.tx``, ``root.tz``, ``root.ry`` become
per-frame steps and turns, §4.5), so :func:`read_controls` checks a file with one-line
errors naming it: a ``frame`` column of consecutive whole numbers, every used control of
the rig as a column (the missing ones named), no column that is not a control of the
rig, numbers only and all finite (the column and frame named), at least 3 frames. A
control the rig does not use is accepted only at its default value (it would otherwise
be dropped unseen; a ``rigmap map`` output holds every control, the unused ones at
their defaults), and said so in the notes. A parquet has no frame time: it is read at
the rate the caller gives (``--fps``, default :data:`CORPUS_FPS`), which the model
records.

Rig mode needs the rig's root on the ground (three root controls) and the joints that
place the heading frame: :data:`RIG_ROOTS` names them per rig — the built-in biped and
quadruped (Y-up: ``root.tx``, ``root.tz``, ``root.ry``; ``pelvis``, ``thigh_l``,
``thigh_r``) and Blender's Rigify human (Z-up: ``root.tx``, ``root.ty``, ``root.rz``,
signs 1, -1, 1 to rigmap's axes, :mod:`rigmap.edits.rig_mode`; ``DEF-spine``, the hips,
and ``DEF-thigh.L``/``DEF-thigh.R``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

import rigmap.rigs
from rigmap.edits.pairs import PairError, pair_scale
from rigmap.edits.propagation import EditModel
from rigmap.edits.representation import TargetTrack
from rigmap.edits.rig_mode import RigChannels, rig_targets
from rigmap.edits.subjects import Subject, rig_subject
from rigmap.store import atomic_file

FRAME_COLUMN = "frame"
#: what ``rigmap map`` writes for one clip (:mod:`rigmap.map.outputs`): its controls, its summary
MAP_CONTROLS, MAP_SUMMARY = "controls.parquet", "summary.json"


@dataclass(frozen=True)
class RigRoot:
    """Where a rig keeps its ground placement: the root controls (x, z, turn), their signs
    to rigmap's Y-up axes, and the root, left and right joints of the heading frame."""

    controls: tuple[str, str, str]
    signs: tuple[float, float, float]
    heading_joints: tuple[str, str, str]


_Y_UP = RigRoot(
    ("root.tx", "root.tz", "root.ry"), (1.0, 1.0, 1.0), ("pelvis", "thigh_l", "thigh_r")
)
#: the rigs rig mode takes. Rigify's human is Z-up: its root's ``tx`` is rigmap's x, ``ty``
#: rigmap's -z and ``rz`` the turn about rigmap's +Y (conf/rig/rigify_human.yaml; checked
#: against ``rig.pose`` in tests/test_edits_blend_rig.py)
RIG_ROOTS = {
    "biped": _Y_UP,
    "quadruped": _Y_UP,
    "rigify_human": RigRoot(
        ("root.tx", "root.ty", "root.rz"),
        (1.0, -1.0, 1.0),
        ("DEF-spine", "DEF-thigh.L", "DEF-thigh.R"),
    ),
}
#: the rate of the rigs' motion library and corpus (``rigmap.animation.library`` clips play at
#: 24 fps): what a controls parquet, which has no frame time, is read at unless told
CORPUS_FPS = 24.0
#: an unused control this close to its default (relative, at least 1e-9 absolute) is at it (ours)
DEFAULT_TOLERANCE = 1e-9


@dataclass(frozen=True, eq=False)
class RigMode:
    """A built-in rig in rig mode: the rig, its :class:`Subject` (channels, feature joints,
    joint positions) and the frame rate its controls parquets are read at."""

    rig: object
    subject: Subject
    fps: float
    root: RigRoot

    @classmethod
    def of(cls, rig_name: str, fps: float = CORPUS_FPS) -> RigMode:
        """The rig ``rig_name`` (``--rig``), checked for rig mode; ``fps`` (``--fps``) too."""
        fps = float(fps)
        if not np.isfinite(fps) or fps <= 0:
            raise PairError(f"--fps must be a positive number of frames per second, got {fps:g}")
        try:
            rig = rigmap.rigs.load(rig_name)
        except rigmap.rigs.UnknownRigError as error:
            raise PairError(f"--rig {rig_name}: {error}") from None
        root = RIG_ROOTS.get(rig.name)
        if root is None:
            raise PairError(
                f"--rig {rig_name}: rig mode needs the rig's root ground controls (x, z, turn: "
                f"root.tx, root.tz, root.ry on the biped) and heading joints, known for "
                f"{sorted(RIG_ROOTS)} only"
            )
        missing = [c for c in root.controls if c not in rig.used_controls]
        if missing:
            raise PairError(
                f"--rig {rig_name}: rig mode needs the root's ground controls {list(root.controls)}"
                f" among the rig's used controls; it lacks {missing}"
            )
        absent = [j for j in root.heading_joints if j not in rig.joint_names]
        if absent:
            raise PairError(
                f"--rig {rig_name}: rig mode needs the joints {list(root.heading_joints)} (they "
                f"place the heading frame); the rig lacks {absent}"
            )
        subject = rig_subject(rig, root.controls, root.heading_joints, root.signs)
        return cls(rig, subject, fps, root)

    @classmethod
    def from_learned(cls, learned: dict, where: str) -> RigMode:
        """The rig mode a model folder's ``learned.json`` records (:meth:`summary`)."""
        try:
            name, fps = str(learned["rig"]), float(learned["fps"])
        except (KeyError, TypeError, ValueError):
            raise PairError(f"{where}: a rig-mode model without its rig name and fps") from None
        mode = cls.of(name, fps)
        recorded = {  # a model learned before signs were recorded: the Y-up rigs' 1, 1, 1
            "root_controls": learned.get("root_controls", list(mode.root.controls)),
            "root_signs": learned.get("root_signs", [1.0, 1.0, 1.0]),
            "heading_joints": learned.get("heading_joints", list(mode.root.heading_joints)),
        }
        now = {k: v for k, v in mode.summary().items() if k in recorded}
        changed = [k for k in recorded if list(recorded[k]) != list(now[k])]
        if changed:
            raise PairError(
                f"{where}: learned with rig {name!r}'s {changed[0]} {list(recorded[changed[0]])}, "
                f"rig mode now uses {now[changed[0]]}: learn the model again"
            )
        return mode

    @property
    def channels(self) -> RigChannels:
        return self.subject.channels

    @property
    def used(self) -> tuple[str, ...]:
        return self.channels.used

    def summary(self) -> dict:
        """What ``learned.json`` records, so ``apply`` and ``fix`` know the mode."""
        return {
            "mode": "rig",
            "rig": self.rig.name,
            "fps": self.fps,
            "root_controls": list(self.root.controls),
            "root_signs": list(self.root.signs),
            "heading_joints": list(self.root.heading_joints),
        }


@dataclass(frozen=True, eq=False)
class RigClip:
    """A controls parquet read for the edits: its used controls ``(F, U)`` in the rig's
    order, the ``frame`` number of its first row, its target track and what was noted."""

    path: str
    controls: np.ndarray
    first_frame: int
    track: TargetTrack
    notes: tuple[str, ...]

    @property
    def frames(self) -> tuple[int, int]:
        """The file's frame numbers ``START:STOP`` of the clip (STOP excluded)."""
        return self.first_frame, self.first_frame + len(self.controls)


@dataclass(frozen=True, eq=False)
class RigPair:
    """An example pair of controls parquets, read and checked; every frame is an example."""

    source: RigClip
    edited: RigClip

    @property
    def examples(self) -> np.ndarray:
        return np.ones(len(self.source.controls), dtype=bool)


def read_controls(path, mode: RigMode, frames: tuple[int, int] | None = None) -> RigClip:
    """One controls parquet, checked (module docstring); ``frames`` ``START:STOP`` are its
    ``frame`` column's numbers (STOP excluded), None the whole file."""
    values, first, notes = read_control_values(path, mode.rig)
    return _clip(path, mode, values, first, notes, frames)


def _clip(path, mode: RigMode, values, first: int, notes, frames) -> RigClip:
    """``frames`` (or all) of a file's checked controls as a clip."""
    start, stop = first, first + len(values)
    if frames is not None:
        start, stop = (int(v) for v in frames)
        if not (first <= start < stop <= first + len(values)) or stop - start < 3:
            raise PairError(
                f"{path}: --frames {start}:{stop} is not a range of at least 3 of its frames "
                f"{first}:{first + len(values)}"
            )
    controls = values[start - first : stop - first].copy()
    track = rig_targets(controls, mode.channels, mode.fps, source=str(path))
    return RigClip(str(path), controls, start, track, tuple(notes))


def read_control_values(path, rig, min_frames: int = 3) -> tuple[np.ndarray, int, list[str]]:
    """``(F, U)`` the used controls of a controls parquet (checked: module docstring), its
    first frame number and the notes; a clip needs 3 frames (its steps and accelerations),
    a fix (:mod:`rigmap.edits.fixes`) one."""
    table = _read_table(path, min_frames)
    first = _frame_numbers(table, path)
    values, notes = _used_values(table, path, rig, first)
    return values, first, notes


def _read_table(path, min_frames: int) -> pd.DataFrame:
    path = Path(path)
    if not path.is_file():
        raise PairError(f"{path}: no such controls parquet")
    try:
        table = pd.read_parquet(path)
    except Exception as error:  # pyarrow raises several kinds for a damaged file
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise PairError(f"{path}: not a readable parquet file ({reason})") from None
    if FRAME_COLUMN not in table.columns:
        raise PairError(
            f"{path}: no {FRAME_COLUMN!r} column (a controls parquet, as rigmap map writes it, "
            "has a frame column and one column per control)"
        )
    if len(table) < min_frames:
        raise PairError(f"{path}: {len(table)} frames; at least {min_frames} are needed")
    return table


def _frame_numbers(table: pd.DataFrame, path) -> int:
    """The first frame number, after checking the column counts up by one per row."""
    column = table[FRAME_COLUMN]
    if not pd.api.types.is_numeric_dtype(column) or pd.api.types.is_bool_dtype(column):
        raise PairError(f"{path}: the {FRAME_COLUMN!r} column holds {column.dtype}, not numbers")
    frames = column.to_numpy(dtype=np.float64)
    if not np.isfinite(frames).all() or np.any(frames != np.round(frames)):
        row = int(np.flatnonzero(~np.isfinite(frames) | (frames != np.round(frames)))[0])
        raise PairError(f"{path}: frame {frames[row]!r} (row {row}) is not a whole number")
    jumps = np.flatnonzero(np.diff(frames) != 1)
    if len(jumps):
        row = int(jumps[0])
        raise PairError(
            f"{path}: the {FRAME_COLUMN!r} column is not consecutive: frame {frames[row]:g} "
            f"(row {row}) is followed by {frames[row + 1]:g}"
        )
    return int(frames[0])


def _used_values(table: pd.DataFrame, path, rig, first: int) -> tuple[np.ndarray, list[str]]:
    """``(F, U)`` the used controls of the table, checked; the notes on unused columns."""
    names = [str(c) for c in table.columns if c != FRAME_COLUMN]
    known = set(rig.control_names)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise PairError(
            f"{path}: columns {_listed(unknown)} are not controls of rig {rig.name!r} (a "
            "controls parquet holds frame and the rig's controls only)"
        )
    used = list(rig.used_controls)
    missing = [n for n in used if n not in table.columns]
    if missing:
        raise PairError(
            f"{path}: lacks {len(missing)} of the {len(used)} used controls of rig "
            f"{rig.name!r}: {_listed(missing)}"
        )
    for name in names:
        column = table[name]
        if not pd.api.types.is_numeric_dtype(column) or pd.api.types.is_bool_dtype(column):
            raise PairError(f"{path}: column {name!r} holds {column.dtype}, not numbers")
    values = table[names].to_numpy(dtype=np.float64)
    bad = np.argwhere(~np.isfinite(values))
    if len(bad):
        row, column = bad[0]
        raise PairError(
            f"{path}: column {names[column]!r} is not a finite number at frame {first + row} "
            f"({float(values[row, column])})"
        )
    return table[used].to_numpy(dtype=np.float64), _unused_notes(table, path, rig, names, first)


def _unused_notes(table: pd.DataFrame, path, rig, names: list[str], first: int) -> list[str]:
    """Controls the rig does not use: refused unless at their defaults (then noted)."""
    used = set(rig.used_controls)
    unused = [n for n in names if n not in used]
    if not unused:
        return []
    defaults = rig.controls.defaults[[rig.control_names.index(n) for n in unused]]
    values = table[unused].to_numpy(dtype=np.float64)
    off = np.abs(values - defaults) > DEFAULT_TOLERANCE * np.maximum(1.0, np.abs(defaults))
    if off.any():
        row, column = np.argwhere(off)[0]
        moved = [unused[k] for k in np.flatnonzero(off.any(axis=0))]
        raise PairError(
            f"{path}: controls rig {rig.name!r} does not use are off their defaults: "
            f"{_listed(moved)} (first {unused[column]!r} at frame {first + row}); rig mode "
            "edits the used controls only and would drop them"
        )
    return [
        f"{path}: {len(unused)} controls the rig does not use, all at their defaults: "
        "read as such (not edited, not written)"
    ]


def _listed(names: list[str], shown: int = 8) -> str:
    more = f" and {len(names) - shown} more" if len(names) > shown else ""
    return f"{names[:shown]}{more}"


def read_rig_pair(source, edited, frames, mode: RigMode) -> RigPair:
    """One example pair (§3: "the source and target clips are assumed to have the same
    number of frames"): the same frame numbers in both files, then ``frames`` of both."""
    (a, a_first, a_notes), (b, b_first, b_notes) = (
        read_control_values(p, mode.rig) for p in (source, edited)
    )
    if len(b) != len(a):
        raise PairError(
            f"{edited}: {len(b)} frames, but its source {source} has "
            f"{len(a)} (§3: a source and its edit have the same number of frames)"
        )
    if b_first != a_first:
        raise PairError(
            f"{edited}: frames {b_first}:{b_first + len(b)}, its source {source} "
            f"{a_first}:{a_first + len(a)} (a pair's frame columns must match)"
        )
    return RigPair(
        _clip(source, mode, a, a_first, a_notes, frames),
        _clip(edited, mode, b, b_first, b_notes, frames),
    )


def learn_rig_pairs(
    pairs: list[RigPair], model: EditModel, subject: Subject, extra: list[tuple] = ()
) -> EditModel:
    """Fit ``model`` (made on ``subject.joints``) on the pairs, the channel scale from their
    source clips (:func:`rigmap.edits.pairs.pair_scale`); ``extra``: more
    ``(source, edited track, frame mask)`` examples (the artist's fixes)."""
    if not pairs:
        raise PairError("give at least one example pair (--source and --edited)")
    scale = pair_scale([p.source.track for p in pairs])
    examples = [(subject.source(p.source.track), p.edited.track) for p in pairs]
    return model.fit([*examples, *extra], scale)


def controls_inputs(path) -> list[tuple[str, Path]]:
    """``(name, controls parquet)`` of every clip ``path`` holds, sorted by name.

    ``path`` is a controls parquet (named by its stem); a ``rigmap map`` output folder (its
    ``controls.parquet``, named by the folder: its other parquets are per-frame errors and
    targets, not controls); or a folder of either. None is an error.
    """
    path = Path(path)
    if path.is_file():
        if path.suffix.lower() != ".parquet":
            raise PairError(
                f"{path}: not a .parquet; a rig-mode edit takes controls parquets (a BVH goes "
                "with a model learned on BVH pairs)"
            )
        return [(path.stem, path)]
    if not path.is_dir():
        raise PairError(f"{path}: no such controls parquet or folder")
    if is_map_output(path):
        return [(path.name, path / MAP_CONTROLS)]
    entries = sorted(path.iterdir())
    found = [(p.stem, p) for p in entries if p.is_file() and p.suffix.lower() == ".parquet"]
    found += [(p.name, p / MAP_CONTROLS) for p in entries if p.is_dir() and is_map_output(p)]
    if not found:
        raise PairError(
            f"{path}: the folder holds no .parquet file and no `rigmap map` output folder (a "
            "rig-mode edit takes controls parquets)"
        )
    return sorted(found)


def is_map_output(folder: Path) -> bool:
    """Whether ``folder`` is one clip's ``rigmap map`` output: its controls and its summary."""
    from rigmap.map.outputs import SUMMARY_FORMAT

    summary = folder / MAP_SUMMARY
    if not ((folder / MAP_CONTROLS).is_file() and summary.is_file()):
        return False
    try:
        record = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(record, dict) and record.get("format") == SUMMARY_FORMAT


def controls_table(controls: np.ndarray, used, first_frame: int = 0) -> pd.DataFrame:
    """``frame`` (from ``first_frame``) and one column per used control."""
    table = pd.DataFrame(np.asarray(controls, dtype=np.float64), columns=list(used))
    table.insert(0, FRAME_COLUMN, np.arange(len(table), dtype=np.int64) + int(first_frame))
    return table


def write_controls(path, table: pd.DataFrame) -> Path:
    """The table as a parquet, atomically (whole or not at all)."""
    with atomic_file(path, suffix=".parquet") as staging:
        table.to_parquet(staging, index=False)
    return Path(path)
