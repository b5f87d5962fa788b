"""Joint tracks: the positions of named joints over time, whatever tool made them.

A mapping's input is joint positions (§3.2), so every source — a BVH file, another
tool's export, a few effector targets — becomes one :class:`JointTracks`: ``(F, J, 3)``
positions of ``J`` named joints over ``F`` frames at ``fps``, in a stated length unit.
Axes stay the source's own here; :class:`rigmap.map.JointMap` converts them.

Files (one clip each):
- ``.bvh``: forward kinematics of the file's channels; end sites become ``<parent>_end``;
- ``.parquet`` / ``.csv``: a ``frame`` column and ``<joint>.x``, ``<joint>.y``, ``<joint>.z``
  per joint (the column layout of rigmap's poses files);
- ``.npz``: ``positions`` ``(F, J, 3)`` and ``joint_names``; optional ``fps``. Given a
  :class:`FrameWindow`, only the window's frames are read from the archive (a long clip
  costs the memory of the frames mapped, not of the file).
"""

from __future__ import annotations

import os
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.animation.bvh import read_bvh
from rigmap.errors import RigmapError
from rigmap.memory import check_memory

AXES = ("x", "y", "z")
LENGTH_UNITS_CM = {"mm": 0.1, "cm": 1.0, "m": 100.0, "in": 2.54}
SOURCE_UNIT = "source"  # a file's own unit (CMU BVH): scaled from bone lengths
NPZ_BLOCK_BYTES = 16 * 2**20  # bytes of an npz read at once while cutting a window (ours)


class TracksError(RigmapError, ValueError):
    """Joint tracks that cannot be used; the message names the file and what is wrong."""


@dataclass(frozen=True)
class FrameWindow:
    """The source frames a run maps: from ``first``, every ``step``-th frame (the step that
    brings the source rate nearest ``fps``; ``None``: every frame), at most ``count`` of them.
    ``options`` names the settings in messages (``rigmap map``'s ``map.*``)."""

    first: int = 0
    count: int | None = None
    fps: float | None = None
    options: str = "map.first_frame, map.frames, map.fps"
    max_frames: int | None = None
    max_option: str = "map.max_frames"

    def step(self, source_fps: float) -> int:
        return 1 if self.fps is None else max(1, round(source_fps / self.fps))

    def slice(self, source_fps: float) -> slice:
        step = self.step(source_fps)
        stop = None if self.count is None else self.first + self.count * step
        return slice(self.first, stop, step)

    def describe(self) -> str:
        first, count, fps = self.options.split(", ")
        return f"{first}={self.first}, {count}={self.count}, {fps}={self.fps}"

    def check_length(self, source_frames: int, source_fps: float, where) -> int:
        """The frames the window takes from a clip of ``source_frames``; ``TracksError``
        naming the cap when they are more than ``max_frames`` (checked before the work and
        the arrays they would need exist)."""
        frames = len(range(source_frames)[self.slice(source_fps)])
        if self.max_frames is not None and frames > self.max_frames:
            count = self.options.split(", ")[1]
            raise TracksError(
                f"{where}: {frames} frames to map, more than {self.max_option}="
                f"{self.max_frames}; set {count} to 1..{self.max_frames} (or raise "
                f"{self.max_option})"
            )
        return frames


@dataclass(frozen=True)
class JointTracks:
    """``positions[f, j]`` is joint ``joint_names[j]`` at frame ``f`` (``unit``, source axes)."""

    joint_names: tuple[str, ...]
    positions: np.ndarray
    fps: float
    unit: str
    source: str = "<tracks>"

    def __post_init__(self) -> None:
        positions = np.asarray(self.positions, dtype=np.float64)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        where = self.source
        if positions.ndim != 3 or positions.shape[2] != 3:
            raise TracksError(
                f"{where}: positions have shape {positions.shape}, expected (F, J, 3)"
            )
        if positions.shape[0] == 0:
            raise TracksError(f"{where}: the clip is empty (0 frames)")
        if positions.shape[1] != len(self.joint_names):
            raise TracksError(
                f"{where}: {positions.shape[1]} joints of positions for "
                f"{len(self.joint_names)} joint names"
            )
        duplicates = sorted({n for n in self.joint_names if self.joint_names.count(n) > 1})
        if duplicates:
            raise TracksError(f"{where}: joint names repeat: {duplicates}")
        bad = ~np.isfinite(positions)
        if bad.any():
            frame, joint, axis = np.argwhere(bad)[0]
            raise TracksError(
                f"{where}: joint {self.joint_names[joint]!r} {AXES[axis]} is "
                f"{positions[frame, joint, axis]} at frame {frame} ({int(bad.any(axis=2).sum())} "
                "bad joint positions in all); positions must be finite numbers"
            )
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise TracksError(f"{where}: fps is {self.fps}, expected a positive number")
        if self.unit not in LENGTH_UNITS_CM and self.unit != SOURCE_UNIT:
            raise TracksError(
                f"{where}: unknown length unit {self.unit!r}; expected one of "
                f"{', '.join([*LENGTH_UNITS_CM, SOURCE_UNIT])}"
            )

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    def index(self, name: str) -> int:
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise TracksError(f"{self.source}: no joint named {name!r}") from None

    def subset(self, names: list[str] | tuple[str, ...]) -> JointTracks:
        """The tracks of ``names`` only, in that order."""
        columns = [self.index(n) for n in names]
        return JointTracks(
            tuple(names), self.positions[:, columns], self.fps, self.unit, self.source
        )


def tracks_from_bvh(path: str | os.PathLike) -> JointTracks:
    """World positions of every joint and end site of a BVH file (its own unit and axes)."""
    return tracks_from_motion(read_bvh(path), str(path))


def tracks_from_motion(motion, source: str) -> JointTracks:
    """World positions of every joint and end site (``<parent>_end``) of a parsed BVH."""
    if motion.n_frames == 0:
        raise TracksError(f"{source}: the BVH file has no frames")
    names = (*motion.joint_names, *motion.end_site_names)
    return JointTracks(
        names, motion.global_positions(end_sites=True), motion.fps, SOURCE_UNIT, source
    )


def read_tracks(
    path: str | os.PathLike,
    *,
    unit: str,
    fps: float | None = None,
    window: FrameWindow | None = None,
    fps_option: str = "map.source_fps",
) -> JointTracks:
    """Joint tracks from a ``.bvh``, ``.parquet``, ``.csv`` or ``.npz`` file.

    ``unit`` is the file's length unit (``cm``, ``m``, ``mm``, ``in`` or ``source``); a BVH
    is always ``source``. ``fps`` is required unless the file carries it (BVH, npz);
    ``fps_option`` is the setting that gives it, named when it is missing. ``window``: an
    npz is read for those frames only (the tracks' fps is then the window's rate); other
    formats ignore it (the caller cuts them).
    """
    path = Path(path)
    if path.is_dir():
        raise TracksError(f"{path} is a folder, not a joint tracks file")
    if not path.is_file():
        raise FileNotFoundError(f"joint tracks file {path} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return tracks_from_bvh(path)
    if suffix == ".npz":
        return _read_npz(path, unit, fps, window, fps_option)
    if suffix in (".parquet", ".csv"):
        try:
            table = pd.read_parquet(path) if suffix == ".parquet" else pd.read_csv(path)
        except Exception as error:  # pyarrow and pandas raise many kinds
            raise TracksError(f"{path}: not a readable {suffix[1:]} table ({error})") from None
        return _from_table(table, unit, _need_fps(fps, path, fps_option), str(path))
    raise TracksError(
        f"{path}: unknown joint tracks format {suffix!r}; use .bvh, .parquet, .csv or .npz"
    )


def _need_fps(fps: float | None, path: Path, option: str) -> float:
    if fps is None:
        raise TracksError(
            f"{path}: the file does not say its frame rate; pass {option}=<frames per second>"
        )
    return float(fps)


def _read_npz(
    path: Path, unit: str, fps: float | None, window: FrameWindow | None, fps_option: str
) -> JointTracks:
    if not zipfile.is_zipfile(path):
        raise TracksError(
            f"{path}: not a readable npz archive (not a zip file, as every .npz is: a zip of .npy "
            "arrays)"
        )
    try:
        with zipfile.ZipFile(path) as archive:
            members = {Path(n).stem: n for n in archive.namelist() if n.endswith(".npy")}
            missing = [k for k in ("positions", "joint_names") if k not in members]
            if missing:
                raise TracksError(f"{path}: npz lacks {missing}; it holds {sorted(members)}")
            names = _small_array(archive, members["joint_names"])
            rate = (
                _npz_fps(path, _small_array(archive, members["fps"]))
                if "fps" in members
                else _need_fps(fps, path, fps_option)
            )
            positions = _npz_rows(archive, members["positions"], rate, window, path)
    except (zipfile.BadZipFile, OSError, EOFError, zlib.error) as error:
        raise TracksError(f"{path}: not a readable npz archive ({error})") from None
    if window is not None:
        rate = rate / window.step(rate)
    return JointTracks(tuple(str(n) for n in names), positions, rate, unit, str(path))


def _npz_fps(path: Path, value: np.ndarray) -> float:
    if value.shape != () or value.dtype.kind not in "iuf":
        raise TracksError(
            f"{path}: 'fps' is {value.dtype} of shape {value.shape}, expected "
            "one number (frames per second)"
        )
    return float(value)


def _small_array(archive: zipfile.ZipFile, member: str) -> np.ndarray:
    """One array of the archive, read whole (no pickled objects)."""
    with archive.open(member) as stream:
        try:
            return np.lib.format.read_array(stream, allow_pickle=False)
        except ValueError as error:
            raise TracksError(f"{archive.filename}: {member}: {error}") from None


def _npz_rows(archive, member: str, rate: float, window, path: Path) -> np.ndarray:
    """``positions`` (float64), only the rows ``window`` selects when it is given: read by
    seeking past the rows before it, in blocks, so memory holds the kept rows only."""
    with archive.open(member) as stream:
        version = np.lib.format.read_magic(stream)
        read_header = (
            np.lib.format.read_array_header_1_0
            if version == (1, 0)
            else np.lib.format.read_array_header_2_0
        )
        try:
            shape, fortran, dtype = read_header(stream)
        except ValueError as error:
            raise TracksError(f"{path}: {member}: {error}") from None
        if dtype.hasobject or dtype.kind not in "iuf" or len(shape) != 3:
            raise TracksError(
                f"{path}: positions are {dtype} of shape {shape}; expected "
                "numbers of shape (F, J, 3)"
            )
        cut = range(shape[0])[window.slice(rate)] if window is not None else range(shape[0])
        if window is not None:
            window.check_length(shape[0], rate, path)
        if window is not None and len(cut) == 0:
            raise TracksError(
                f"{path}: no frames left to map (the clip has {shape[0]} frames; "
                f"{window.describe()})"
            )
        if window is not None:
            check_memory(
                len(cut) * int(np.prod(shape[1:])) * 8,
                window.options.split(", ")[1],
                window.count,
                f"{len(cut)} frames of {shape[1]} joints",
            )
        if fortran:  # rows are not contiguous: read whole (rare: numpy writes C order)
            whole = np.frombuffer(stream.read(), dtype=dtype).reshape(shape[::-1]).T
            return np.asarray(whole[cut.start : cut.stop : cut.step], dtype=np.float64)
        row = int(np.prod(shape[1:])) * dtype.itemsize
        offset = stream.tell()
        out = np.empty((len(cut), *shape[1:]), dtype=np.float64)
        block = max(1, NPZ_BLOCK_BYTES // max(row * cut.step, 1))
        for k in range(0, len(cut), block):
            rows = cut[k : k + block]
            stream.seek(offset + rows[0] * row)
            raw = stream.read((rows[-1] - rows[0] + 1) * row)
            if len(raw) < (rows[-1] - rows[0] + 1) * row:
                raise TracksError(f"{path}: {member} is truncated")
            chunk = np.frombuffer(raw, dtype=dtype).reshape(-1, *shape[1:])
            out[k : k + len(rows)] = chunk[:: cut.step]
        return out


def _from_table(table: pd.DataFrame, unit: str, fps: float, source: str) -> JointTracks:
    """``<joint>.x/.y/.z`` columns in their order of appearance; each joint needs all three."""
    joints: dict[str, set[str]] = {}
    for column in table.columns:
        joint, dot, axis = str(column).rpartition(".")
        if dot and axis in AXES:
            joints.setdefault(joint, set()).add(axis)
    if not joints:
        raise TracksError(f"{source}: no '<joint>.x/.y/.z' columns among {list(table.columns)[:8]}")
    incomplete = {j: sorted(set(AXES) - axes) for j, axes in joints.items() if axes != set(AXES)}
    if incomplete:
        raise TracksError(f"{source}: joints missing coordinate columns: {incomplete}")
    if "frame" in table.columns:
        frames = table["frame"].to_numpy()
        if len(frames) > 1 and not (np.diff(frames) == 1).all():
            raise TracksError(f"{source}: the frame column is not consecutive frame numbers")
    names = tuple(joints)
    columns = [f"{j}.{a}" for j in names for a in AXES]
    try:
        values = table[columns].to_numpy(dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise TracksError(f"{source}: joint columns are not all numbers ({error})") from None
    return JointTracks(names, values.reshape(len(table), len(names), 3), fps, unit, source)
