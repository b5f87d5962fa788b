"""Live Link Face CSV takes in and out: real ARKit face curves as training data and results.

Apple's Live Link Face app exports one row per sample: ``Timecode`` (``HH:MM:SS:FF.fff``,
frames at the timecode's rate with a sub-frame fraction), ``BlendShapeCount`` (0 where the
face was lost: such rows hold no values), ARKit's 52 blendshape weights and the head/eye
rotations (radians). :func:`read_take` parses a file, checks it (one-line errors naming
the file and line) and finds dropped samples (steps in the timecode longer than the
take's usual one), lost-tracking rows and duplicated timecodes;
:meth:`LiveLinkTake.segments` resamples the tracked samples to a uniform rate, cut where
tracking was lost for longer than a few samples. :func:`write_take` writes curves back in
the same format, so a synthesised result plays on any ARKit-driven face.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rigmap.latent.errors import LatentInputError

#: the app's 52 blendshape columns, in its order (ARKit's names with a capital first letter)
BLENDSHAPES = (
    "EyeBlinkLeft",
    "EyeLookDownLeft",
    "EyeLookInLeft",
    "EyeLookOutLeft",
    "EyeLookUpLeft",
    "EyeSquintLeft",
    "EyeWideLeft",
    "EyeBlinkRight",
    "EyeLookDownRight",
    "EyeLookInRight",
    "EyeLookOutRight",
    "EyeLookUpRight",
    "EyeSquintRight",
    "EyeWideRight",
    "JawForward",
    "JawRight",
    "JawLeft",
    "JawOpen",
    "MouthClose",
    "MouthFunnel",
    "MouthPucker",
    "MouthRight",
    "MouthLeft",
    "MouthSmileLeft",
    "MouthSmileRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "MouthDimpleLeft",
    "MouthDimpleRight",
    "MouthStretchLeft",
    "MouthStretchRight",
    "MouthRollLower",
    "MouthRollUpper",
    "MouthShrugLower",
    "MouthShrugUpper",
    "MouthPressLeft",
    "MouthPressRight",
    "MouthLowerDownLeft",
    "MouthLowerDownRight",
    "MouthUpperUpLeft",
    "MouthUpperUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BrowInnerUp",
    "BrowOuterUpLeft",
    "BrowOuterUpRight",
    "CheekPuff",
    "CheekSquintLeft",
    "CheekSquintRight",
    "NoseSneerLeft",
    "NoseSneerRight",
    "TongueOut",
)
#: the rotation columns after them (radians; the shared takes leave the head's at zero)
ROTATIONS = (
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
)
VALUE_COLUMNS = BLENDSHAPES + ROTATIONS
HEADER = ("Timecode", "BlendShapeCount", *VALUE_COLUMNS)
TIMECODE_FPS = 60  # the app's timecode rate in the shared takes (a 60 fps timecode, step 2)
RESAMPLE_FPS = 30.0  # ours: the capture's own rate, so resampling invents no detail
MAX_GAP_S = 0.25  # ours: the longest hole interpolated across; longer ones cut the take
MIN_SEGMENT_FRAMES = 2  # ours: a shorter tracked stretch between losses has no motion
DROP_STEP = 1.5  # ours: a step over 1.5 × the take's median step has dropped samples
DECIMALS = 10  # the app's: ten decimals, so a value written and read back moves < 1e-10
TIMECODE = re.compile(r"^(\d{1,2}):(\d{2}):(\d{2}):(\d{2,3}(?:\.\d+)?)$")
DAY_S = 86400.0


class LiveLinkError(LatentInputError):
    """A Live Link Face CSV that cannot be read as a take (file and line named)."""


def arkit_name(column: str) -> str:
    """ARKit's own name of a blendshape column (``JawOpen`` → ``jawOpen``)."""
    return column[:1].lower() + column[1:]


def live_link_columns(controls) -> tuple[str, ...]:
    """The Live Link Face column of each control of a rig whose controls are ARKit's
    (named as the columns or as ARKit names them); any other control is an error."""
    by_name = {name: name for name in VALUE_COLUMNS}
    by_name.update({arkit_name(name): name for name in VALUE_COLUMNS})
    columns = []
    for control in controls:
        if control not in by_name:
            raise LiveLinkError(
                f"control {control!r} is not an ARKit blendshape or eye/head rotation "
                f"(e.g. jawOpen or JawOpen); a Live Link Face CSV holds only those"
            )
        columns.append(by_name[control])
    if len(set(columns)) != len(columns):
        raise LiveLinkError(f"controls {list(controls)} name one Live Link Face column twice")
    return tuple(columns)


@dataclass(frozen=True)
class Segment:
    """A stretch of a take resampled to ``fps``: ``values`` ``(F, C)`` from ``start_s``."""

    start_s: float
    fps: float
    values: np.ndarray
    interpolated: int  # frames strictly inside a dropped-sample hole


@dataclass
class LiveLinkTake:
    """A parsed take: its tracked samples (times in seconds of the day, sorted) and what
    was wrong with the rest (file line numbers, header = line 1)."""

    path: Path
    columns: tuple[str, ...]
    times: np.ndarray  # (N,) tracked samples
    values: np.ndarray  # (N, C) in ``columns`` order
    lines: np.ndarray  # (N,) each tracked sample's file line
    timecode_fps: float
    step_s: float  # the median step between rows (1 / the capture's rate)
    lost_lines: list[int] = field(default_factory=list)
    duplicate_lines: list[int] = field(default_factory=list)
    gaps: list[dict] = field(default_factory=list)  # dropped samples: after line, seconds, n
    span_s: tuple[float, float] = (0.0, 0.0)  # first and last row's time, tracked or not

    @property
    def duration_s(self) -> float:
        return float(self.times[-1] - self.times[0])

    @property
    def dropped_samples(self) -> int:
        return sum(gap["samples"] for gap in self.gaps)

    def curves(self, names=None) -> np.ndarray:
        """The tracked samples' values of ``names`` (default every column), ``(N, len)``."""
        names = self.columns if names is None else tuple(names)
        unknown = [name for name in names if name not in self.columns]
        if unknown:
            raise LiveLinkError(f"{self.path}: no column {unknown[0]!r}; columns: {self.columns}")
        return self.values[:, [self.columns.index(name) for name in names]]

    def report(self) -> dict:
        """Duration, rates and what was dropped, lost or repeated (JSON-ready)."""
        span, rows = self.span_s[1] - self.span_s[0], len(self.times) + len(self.lost_lines)
        return {
            "file": self.path.name,
            "rows": rows + len(self.duplicate_lines),
            "tracked_samples": len(self.times),
            "duration_s": round(span, 4),
            "tracked_s": round(self.duration_s, 4),
            "timecode_fps": self.timecode_fps,
            "sample_rate_hz": round(1.0 / self.step_s, 3),
            "mean_rate_hz": round((rows - 1) / span, 3) if span > 0 else None,
            "dropped_samples": self.dropped_samples,
            "gaps": self.gaps,
            "lost_tracking_rows": len(self.lost_lines),
            "lost_tracking_runs": _runs(self.lost_lines),
            "duplicate_rows": len(self.duplicate_lines),
        }

    def segments(
        self, fps: float = RESAMPLE_FPS, *, max_gap_s: float = MAX_GAP_S, min_frames: int = 1
    ) -> list[Segment]:
        """The tracked samples linearly resampled to ``fps``: holes up to ``max_gap_s``
        (dropped samples) are interpolated, longer ones (lost tracking) cut the take.
        Fewer than ``min_frames`` frames in all is an error naming the file."""
        if not (np.isfinite(fps) and fps > 0):
            raise LiveLinkError(f"{self.path}: resample rate must be a positive number, got {fps}")
        cuts = np.flatnonzero(np.diff(self.times) > max_gap_s) + 1
        out = []
        for rows in np.split(np.arange(len(self.times)), cuts):
            if len(rows) < MIN_SEGMENT_FRAMES:
                continue
            t = self.times[rows]
            count = int(np.floor((t[-1] - t[0]) * fps + 1e-6)) + 1
            grid = t[0] + np.arange(count) / fps
            values = np.column_stack([np.interp(grid, t, v) for v in self.values[rows].T])
            holes = np.diff(t) > DROP_STEP * self.step_s
            inside = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 2)
            off = np.minimum(grid - t[inside], t[inside + 1] - grid) > 1e-9  # not on a sample
            between = holes[inside] & off
            out.append(Segment(float(t[0]), float(fps), values, int(between.sum())))
        total = sum(len(s.values) for s in out)
        if total < min_frames:
            raise LiveLinkError(
                f"{self.path}: {total} frames at {fps:g} fps after dropping lost tracking "
                f"(lines {int(self.lines[0])}-{int(self.lines[-1])}), fewer than the "
                f"{min_frames} needed"
            )
        return out


def _runs(lines: list[int]) -> list[list[int]]:
    """Consecutive line numbers as ``[first, last]`` runs."""
    runs: list[list[int]] = []
    for line in lines:
        if runs and line == runs[-1][1] + 1:
            runs[-1][1] = line
        else:
            runs.append([line, line])
    return runs


def timecode_seconds(text: str, fps: float, where: str) -> float:
    """``HH:MM:SS:FF.fff`` at ``fps`` frames a second → seconds of the day."""
    match = TIMECODE.match(text.strip())
    if match is None:
        raise LiveLinkError(f"{where}: timecode {text!r} is not HH:MM:SS:FF.fff")
    hours, minutes, seconds, frames = match.groups()
    h, m, s, f = int(hours), int(minutes), int(seconds), float(frames)
    if h >= 24 or m >= 60 or s >= 60 or f >= fps:
        raise LiveLinkError(
            f"{where}: timecode {text!r} is out of range (frames must be below the "
            f"timecode rate {fps:g}; timecode_fps names another)"
        )
    return h * 3600.0 + m * 60.0 + s + f / fps


def read_header(path: Path, header: list[str]) -> tuple[str, ...]:
    """The value columns of a header, checked against the app's names."""
    if header[:2] != ["Timecode", "BlendShapeCount"]:
        raise LiveLinkError(
            f"{path}, line 1: a Live Link Face CSV starts with Timecode,BlendShapeCount; "
            f"got {','.join(header[:2])!r}"
        )
    columns = tuple(name.strip() for name in header[2:])
    for k, name in enumerate(columns):
        if name not in VALUE_COLUMNS:
            raise LiveLinkError(
                f"{path}, line 1: unknown column {name!r} (column {k + 3}); Live Link Face "
                f"columns are the 52 ARKit blendshapes ({BLENDSHAPES[0]} … {BLENDSHAPES[-1]}) "
                f"and {', '.join(ROTATIONS)}"
            )
        if name in columns[:k]:
            raise LiveLinkError(f"{path}, line 1: column {name!r} appears twice")
    missing = [name for name in BLENDSHAPES if name not in columns]
    if missing:
        raise LiveLinkError(f"{path}, line 1: no column for the blendshapes {missing}")
    return columns


def _row_values(row: list[str], columns: tuple[str, ...], where: str) -> np.ndarray:
    if len(row) != len(columns) + 2:
        raise LiveLinkError(
            f"{where}: {len(row)} fields, the header has {len(columns) + 2} (and the row "
            f"is not a lost-tracking row: BlendShapeCount is {row[1]!r}, not 0)"
        )
    values = np.empty(len(columns))
    for k, text in enumerate(row[2:]):
        try:
            values[k] = float(text)
        except ValueError:
            raise LiveLinkError(f"{where}: {columns[k]} is {text!r}, not a number") from None
        if not np.isfinite(values[k]):
            raise LiveLinkError(f"{where}: {columns[k]} is {text!r}, not a finite number")
    return values


def _parse_rows(path: Path, reader, columns, timecode_fps):
    """Every data row: (line, seconds, values or None when tracking was lost)."""
    rows, shapes = [], [columns.index(name) for name in BLENDSHAPES]
    for line, row in enumerate(reader, start=2):
        if not row or all(not cell.strip() for cell in row):
            continue
        where = f"{path}, line {line}"
        seconds = timecode_seconds(row[0], timecode_fps, where)
        count = row[1].strip() if len(row) > 1 else ""
        if not count.isdigit():
            raise LiveLinkError(f"{where}: BlendShapeCount is {count!r}, not a whole number")
        values = None if int(count) == 0 else _row_values(row, columns, where)
        if values is not None and not values[shapes].any():
            values = None  # ours: all 52 weights exactly 0 is no face, not a neutral one
        rows.append((line, seconds, values))
    return rows


def read_take(path, *, timecode_fps: float = TIMECODE_FPS) -> LiveLinkTake:
    """Parse and check one Live Link Face CSV (errors name the file and line)."""
    path = Path(path)
    if not path.is_file():
        raise LiveLinkError(f"{path}: no such Live Link Face CSV")
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except UnicodeDecodeError as error:
        raise LiveLinkError(f"{path}: not a UTF-8 text file (byte {error.start})") from None
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if not header:
        raise LiveLinkError(f"{path}: empty file, no header")
    columns = read_header(path, header)
    rows = _parse_rows(path, reader, columns, timecode_fps)
    if not rows:
        raise LiveLinkError(f"{path}: a header and no rows")
    times = _unwrapped([seconds for _, seconds, _ in rows], path, [line for line, *_ in rows])
    return _checked_take(path, columns, rows, times, timecode_fps)


def _unwrapped(seconds: list[float], path: Path, lines: list[int]) -> np.ndarray:
    """Times made increasing across midnight; a step back is an error naming the line."""
    t = np.asarray(seconds)
    back = np.flatnonzero(np.diff(t) < -DAY_S / 2) + 1
    for k in back:
        t[k:] += DAY_S
    wrong = np.flatnonzero(np.diff(t) < 0)
    if len(wrong):
        k = int(wrong[0]) + 1
        raise LiveLinkError(
            f"{path}, line {lines[k]}: the timecode goes back ({t[k] - t[k - 1]:+.4f} s); "
            "rows must be in time order"
        )
    return t


def _checked_take(path, columns, rows, times, timecode_fps) -> LiveLinkTake:
    lines = np.array([line for line, *_ in rows])
    repeated = np.concatenate([[False], np.diff(times) == 0])
    lost = np.array([values is None for *_, values in rows])
    kept = ~repeated & ~lost
    if not kept.any():
        raise LiveLinkError(
            f"{path}: every row ({len(rows)}, lines {lines[0]}-{lines[-1]}) lost tracking "
            "(BlendShapeCount 0 or all blendshapes 0); nothing to train on"
        )
    unique = times[~repeated]
    step = float(np.median(np.diff(unique))) if len(unique) > 1 else 1.0 / RESAMPLE_FPS
    gaps = []
    for k in np.flatnonzero(np.diff(unique) > DROP_STEP * step):
        dt = float(unique[k + 1] - unique[k])
        after = int(lines[~repeated][k])
        gaps.append({"after_line": after, "seconds": round(dt, 5), "samples": round(dt / step) - 1})
    return LiveLinkTake(
        path=path,
        columns=columns,
        times=times[kept],
        values=np.array([values for (*_, values), keep in zip(rows, kept, strict=True) if keep]),
        lines=lines[kept],
        timecode_fps=float(timecode_fps),
        step_s=step,
        lost_lines=[int(x) for x in lines[lost & ~repeated]],
        duplicate_lines=[int(x) for x in lines[repeated]],
        span_s=(float(times[0]), float(times[-1])),
        gaps=gaps,
    )


def timecode_text(milliframes: int, fps: float) -> str:
    """Thousandths of a frame since midnight → ``HH:MM:SS:FF.fff`` at ``fps``."""
    frames_per_day = round(DAY_S * fps * 1000)
    milliframes %= frames_per_day
    whole, sub = divmod(milliframes, 1000)
    seconds, frames = divmod(whole, round(fps))
    return (
        f"{seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}:{frames:02d}.{sub:03d}"
    )


def take_text(
    curves, names, *, fps: float, start_s: float = 0.0, timecode_fps: float = TIMECODE_FPS
) -> str:
    """Curves ``(F, len(names))`` at ``fps`` as a Live Link Face CSV's text: every column
    of the app's header, those not in ``names`` written as 0 (as the app writes the head
    rotations it did not record), values with the app's ten decimals."""
    curves = np.asarray(curves, dtype=np.float64)
    names = tuple(names)
    unknown = [name for name in names if name not in VALUE_COLUMNS]
    if unknown:
        raise LiveLinkError(f"curves: unknown Live Link Face column {unknown[0]!r}")
    if curves.ndim != 2 or curves.shape[1] != len(names) or len(curves) == 0:
        raise LiveLinkError(f"curves: expected (frames ≥ 1, {len(names)}), got {curves.shape}")
    if not np.isfinite(curves).all():
        row = int(np.argwhere(~np.isfinite(curves))[0, 0])
        raise LiveLinkError(f"curves: frame {row} has non-finite values")
    if round(timecode_fps) != timecode_fps or timecode_fps <= 0:
        raise LiveLinkError(f"timecode_fps must be a whole number of frames, got {timecode_fps}")
    step = timecode_fps * 1000.0 / fps  # thousandths of a timecode frame per sample
    if not (fps > 0 and abs(step - round(step)) < 1e-6):
        raise LiveLinkError(
            f"fps {fps:g} is not a whole number of thousandths of a frame of a "
            f"{timecode_fps:g} fps timecode; resample to e.g. 24, 30 or 60 fps first"
        )
    if not 0.0 <= start_s < DAY_S:
        raise LiveLinkError(f"start_s must be a time of the day in seconds, got {start_s}")
    full = np.zeros((len(curves), len(VALUE_COLUMNS)))
    full[:, [VALUE_COLUMNS.index(name) for name in names]] = curves
    start = round(start_s * timecode_fps * 1000)
    out = [",".join(HEADER)]
    count = str(len(VALUE_COLUMNS))
    for i, row in enumerate(full):
        code = timecode_text(start + i * round(step), timecode_fps)
        out.append(",".join([code, count, *(f"{v:.{DECIMALS}f}" for v in row)]))
    return "\n".join(out) + "\n"


def write_take(
    path, curves, names, *, fps: float, start_s: float = 0.0, timecode_fps: float = TIMECODE_FPS
) -> Path:
    """Write curves as a Live Link Face CSV (atomically: no half-written file)."""
    from rigmap.store.atomic import write_text_atomic

    text = take_text(curves, names, fps=fps, start_s=start_s, timecode_fps=timecode_fps)
    return write_text_atomic(Path(path), text)
