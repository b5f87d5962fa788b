"""BVH motion capture: a skeleton, per-frame channel values, and the joint positions they give.

Motion capture is the input an inverse rig mapping exists for: joint positions
from a capture session, to be turned into editable rig controls. A BVH file holds
a joint hierarchy (names, offsets from the parent, channel order per joint) and,
per frame, one number per channel: positions in the file's length unit, Euler
angles in degrees applied in the order the channels are listed (``Zrotation
Yrotation Xrotation`` means ``R = Rz · Ry · Rx`` acting on column vectors, the
child's offset rotated by the parent's global rotation).

The sample clips in ``../shared/mocap/`` are from the CMU Graphics Lab Motion
Capture Database (subject 131, 120 fps, the CMU BVH conversion's own length unit).
Their channel order is not uniform: most joints are ``Zrotation Yrotation
Xrotation`` but the twelve arm and hand joints are ``Zrotation Xrotation
Yrotation``, so the order is always taken per joint from the file.
Credit line, kept wherever the data is used:

    The data used in this project was obtained from mocap.cs.cmu.edu.
    The database was created with funding from NSF EIA-0196217.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError

POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
CHANNEL_NAMES = POSITION_CHANNELS + ROTATION_CHANNELS


class BVHError(RigmapError, ValueError):
    """A BVH file that cannot be read; the message names the file and the line."""


@dataclass(frozen=True, eq=False)
class BVHMotion:
    """A parsed BVH file: the skeleton and the raw channel values of every frame.

    ``values`` is ``(N, channel_count)`` in file order: each joint's channels, joints
    in hierarchy order. ``parents[j]`` is ``-1`` for a root; parents come before
    their children. End sites (the tips of chains, no channels) are kept apart:
    ``end_site_parents`` and ``end_site_offsets``.
    """

    source: str
    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_site_parents: np.ndarray
    end_site_offsets: np.ndarray
    frame_time: float
    values: np.ndarray

    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    @property
    def duration_s(self) -> float:
        return self.n_frames * self.frame_time

    @property
    def channel_count(self) -> int:
        return sum(len(c) for c in self.channels)

    @property
    def end_site_names(self) -> tuple[str, ...]:
        return tuple(f"{self.joint_names[p]}_end" for p in self.end_site_parents)

    def joint_index(self, name: str) -> int:
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"{self.source}: no joint named {name!r}") from None

    def channel_slices(self) -> list[slice]:
        """Per joint, its columns of ``values``."""
        slices, start = [], 0
        for joint_channels in self.channels:
            slices.append(slice(start, start + len(joint_channels)))
            start += len(joint_channels)
        return slices

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """World rotations ``(N, J, 3, 3)`` and positions ``(N, J, 3)`` by forward kinematics."""
        n = self.n_frames
        rotations = np.empty((n, self.n_joints, 3, 3))
        positions = np.empty((n, self.n_joints, 3))
        for j, columns in enumerate(self.channel_slices()):
            names = self.channels[j]
            data = self.values[:, columns]
            local_rotation = np.broadcast_to(np.eye(3), (n, 3, 3))
            translation = np.broadcast_to(self.offsets[j], (n, 3)).copy()
            for k, channel in enumerate(names):
                if channel in POSITION_CHANNELS:
                    translation[:, POSITION_CHANNELS.index(channel)] += data[:, k]
                else:
                    axis = ROTATION_CHANNELS.index(channel)
                    local_rotation = local_rotation @ _axis_rotation(axis, np.radians(data[:, k]))
            parent = self.parents[j]
            if parent < 0:
                rotations[:, j] = local_rotation
                positions[:, j] = translation
            else:
                rotations[:, j] = rotations[:, parent] @ local_rotation
                positions[:, j] = positions[:, parent] + np.einsum(
                    "nab,nb->na", rotations[:, parent], translation
                )
        return rotations, positions

    def global_positions(self, end_sites: bool = False) -> np.ndarray:
        """World joint positions ``(N, J, 3)``; with ``end_sites``, ``(N, J + E, 3)``.

        End sites follow the joints, in ``end_site_names`` order.
        """
        rotations, positions = self.global_transforms()
        if not end_sites or len(self.end_site_parents) == 0:
            return positions
        parent = self.end_site_parents
        tips = positions[:, parent] + np.einsum(
            "njab,jb->nja", rotations[:, parent], self.end_site_offsets
        )
        return np.concatenate([positions, tips], axis=1)


def read_bvh(path: str | os.PathLike) -> BVHMotion:
    """Read and parse a BVH file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"BVH file {path} does not exist")
    return parse_bvh(path.read_text(encoding="utf-8", errors="replace"), source=str(path))


def parse_bvh(text: str, source: str = "<string>") -> BVHMotion:
    """Parse BVH text; ``source`` names it in error messages."""
    lines = text.splitlines()
    motion_line = next((i for i, line in enumerate(lines) if line.strip() == "MOTION"), None)
    if motion_line is None:
        raise BVHError(f"{source}: no MOTION section (the file has only a hierarchy, or none)")
    skeleton = _HierarchyParser(lines[:motion_line], source).parse()
    frame_time, values = _parse_motion(lines, motion_line, skeleton["channel_count"], source)
    return BVHMotion(
        source=source,
        joint_names=tuple(skeleton["names"]),
        parents=np.array(skeleton["parents"], dtype=np.int64),
        offsets=np.array(skeleton["offsets"], dtype=np.float64).reshape(-1, 3),
        channels=tuple(skeleton["channels"]),
        end_site_parents=np.array(skeleton["end_parents"], dtype=np.int64),
        end_site_offsets=np.array(skeleton["end_offsets"], dtype=np.float64).reshape(-1, 3),
        frame_time=frame_time,
        values=values,
    )


class _HierarchyParser:
    """A parser over the HIERARCHY section's words, keeping line numbers."""

    def __init__(self, lines: list[str], source: str):
        self.source = source
        self.words: list[tuple[str, int]] = [
            (word, number) for number, line in enumerate(lines, 1) for word in line.split()
        ]
        self.position = 0
        self.last_line = len(lines)
        self.names: list[str] = []
        self.seen: set[str] = set()
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_parents: list[int] = []
        self.end_offsets: list[list[float]] = []

    def parse(self) -> dict:
        self._expect("HIERARCHY")
        self._expect("ROOT")
        self._joint(parent=-1)
        while self._peek() == "ROOT":
            self._next()
            self._joint(parent=-1)
        if self._peek() is not None:
            word, line = self.words[self.position]
            raise self._error(line, f"unexpected {word!r} after the hierarchy")
        return {
            "names": self.names,
            "parents": self.parents,
            "offsets": self.offsets,
            "channels": self.channels,
            "end_parents": self.end_parents,
            "end_offsets": self.end_offsets,
            "channel_count": sum(len(c) for c in self.channels),
        }

    def _joint(self, parent: int) -> None:
        """A joint and everything under it, with a stack of open joints rather than
        recursion (a hierarchy of any depth, as deep as its file is long)."""
        open_joints = [self._joint_header(parent)]
        while open_joints:
            index, name = open_joints[-1]
            word, line = self._next("'JOINT', 'End Site' or '}'")
            if word == "}":
                open_joints.pop()
            elif word == "JOINT":
                open_joints.append(self._joint_header(index))
            elif word == "End":
                self._expect("Site")
                self._expect("{")
                self._expect("OFFSET")
                self.end_offsets.append(self._numbers(3, "End Site OFFSET"))
                self.end_parents.append(index)
                self._expect("}")
            else:
                raise self._error(
                    line, f"expected 'JOINT', 'End Site' or '}}' in joint {name!r}, got {word!r}"
                )

    def _joint_header(self, parent: int) -> tuple[int, str]:
        """A joint's name, offset and channels; its index and name."""
        name = self._rest_of_line("a joint name")
        if name in self.seen:
            raise self._error(self._line(), f"joint name {name!r} appears twice")
        index = len(self.names)
        self.names.append(name)
        self.seen.add(name)
        self.parents.append(parent)
        self._expect("{")
        self._expect("OFFSET")
        self.offsets.append(self._numbers(3, "OFFSET"))
        self._expect("CHANNELS")
        count_word, count_line = self._next("a channel count")
        if not count_word.isdigit():
            raise self._error(
                count_line, f"channel count must be a whole number, got {count_word!r}"
            )
        names = []
        for _ in range(int(count_word)):
            channel, line = self._next("a channel name")
            if channel not in CHANNEL_NAMES:
                raise self._error(
                    line, f"unknown channel {channel!r} in joint {name!r}; known: {CHANNEL_NAMES}"
                )
            names.append(channel)
        if len(set(names)) != len(names):
            raise self._error(count_line, f"joint {name!r} lists a channel twice: {names}")
        self.channels.append(tuple(names))
        return index, name

    def _numbers(self, count: int, what: str) -> list[float]:
        numbers = []
        for _ in range(count):
            word, line = self._next(f"{count} numbers after {what}")
            try:
                numbers.append(float(word))
            except ValueError:
                raise self._error(line, f"{what} needs {count} numbers, got {word!r}") from None
        return numbers

    def _rest_of_line(self, what: str) -> str:
        first, line = self._next(what)
        parts = [first]
        while self.position < len(self.words) and self.words[self.position][1] == line:
            parts.append(self.words[self.position][0])
            self.position += 1
        return " ".join(parts)

    def _peek(self) -> str | None:
        return self.words[self.position][0] if self.position < len(self.words) else None

    def _line(self) -> int:
        return self.words[max(self.position - 1, 0)][1] if self.words else 1

    def _next(self, what: str = "more hierarchy") -> tuple[str, int]:
        if self.position >= len(self.words):
            raise self._error(self.last_line, f"hierarchy ends early, expected {what}")
        word = self.words[self.position]
        self.position += 1
        return word

    def _expect(self, wanted: str) -> None:
        word, line = self._next(repr(wanted))
        if word != wanted:
            raise self._error(line, f"expected {wanted!r}, got {word!r}")

    def _error(self, line: int, message: str) -> BVHError:
        return BVHError(f"{self.source}, line {line}: {message}")


def _parse_motion(
    lines: list[str], motion_line: int, channel_count: int, source: str
) -> tuple[float, np.ndarray]:
    """Frame time and ``(N, channel_count)`` values from the lines after ``MOTION``."""

    def error(number: int, message: str) -> BVHError:
        return BVHError(f"{source}, line {number}: {message}")

    def header(index: int, label: str) -> str:
        if index >= len(lines):
            raise error(index, f"file ends before the '{label}' line of the MOTION section")
        line = lines[index].strip()
        if not line.startswith(label):
            raise error(index + 1, f"expected '{label} ...', got {line[:60]!r}")
        return line[len(label) :].strip()

    frames_text = header(motion_line + 1, "Frames:")
    if not frames_text.isdigit():
        raise error(motion_line + 2, f"'Frames:' needs a whole number, got {frames_text!r}")
    n_frames = int(frames_text)
    time_text = header(motion_line + 2, "Frame Time:")
    try:
        frame_time = float(time_text)
    except ValueError:
        raise error(motion_line + 3, f"'Frame Time:' needs a number, got {time_text!r}") from None
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise error(motion_line + 3, f"'Frame Time:' must be positive, got {frame_time}")

    rows: list[list[str]] = []
    for index in range(motion_line + 3, len(lines)):
        words = lines[index].split()
        if not words:
            continue
        if len(rows) == n_frames:
            raise error(index + 1, f"more motion lines than the {n_frames} declared by 'Frames:'")
        if len(words) != channel_count:
            raise error(
                index + 1,
                f"frame {len(rows)} has {len(words)} values, expected {channel_count} "
                "(one per channel in the hierarchy)",
            )
        rows.append(words)
    if len(rows) < n_frames:
        raise error(
            len(lines),
            f"truncated: file ends after {len(rows)} of the {n_frames} frames declared by "
            f"'Frames:' (line {motion_line + 2})",
        )
    try:
        values = np.array(rows, dtype=np.float64).reshape(n_frames, channel_count)
    except ValueError:
        values = None
    if values is None or not np.isfinite(values).all():
        _raise_first_bad_value(rows, lines, motion_line + 3, error)
    return frame_time, values


def _raise_first_bad_value(rows, lines, first_index, error) -> None:
    """Find the line of the first value that is not a finite number, and say so."""
    row = 0
    for index in range(first_index, len(lines)):
        if not lines[index].split():
            continue
        for word in rows[row]:
            try:
                number = float(word)
            except ValueError:
                raise error(index + 1, f"value {word!r} is not a number") from None
            if not np.isfinite(number):
                raise error(index + 1, f"value {word!r} is not a finite number")
        row += 1
    raise AssertionError("a bad value was detected but not found")  # pragma: no cover


def _axis_rotation(axis: int, angles: np.ndarray) -> np.ndarray:
    """``(N, 3, 3)`` rotations by ``angles`` (radians) about x (0), y (1) or z (2)."""
    c, s = np.cos(angles), np.sin(angles)
    m = np.zeros((len(angles), 3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m[:, axis, axis] = 1.0
    m[:, i, i] = c
    m[:, j, j] = c
    m[:, i, j] = -s
    m[:, j, i] = s
    return m
