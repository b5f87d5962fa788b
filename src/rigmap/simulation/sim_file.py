"""The simulated mesh as a file: per-frame vertex positions in rigmap's joint-tracks format.

``<name>.npz`` holds ``positions`` ``(F, V, 3)`` (world cm, rigmap's axes: Y up, the
squirrel facing +Z), ``joint_names`` (the rig's vertex "joints", ``v0000`` …), ``fps``,
``faces`` (the triangles, for drawing) and ``scenario`` (the simulation's settings as
JSON text). The first three are exactly what :func:`rigmap.map.tracks.read_tracks` reads
(``rigmap map`` takes such a file, ``map.unit=cm``); the file is read back through it, so a
NaN or a bad shape is refused there with the same one-line messages.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.map.tracks import read_tracks
from rigmap.store import write_bytes_atomic


class VertexInputError(RigmapError, ValueError):
    """Simulated vertices that do not fit the rig: the message names the file and the fault."""


def write_simulation(path, positions, joint_names, fps: float, faces, scenario: dict) -> Path:
    """Write the simulation's file atomically (see the module docstring); returns its path."""
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer,
        positions=np.asarray(positions, dtype=np.float64),
        joint_names=np.asarray(list(joint_names), dtype=str),
        fps=np.float64(fps),
        faces=np.asarray(faces, dtype=np.int64),
        scenario=np.asarray(json.dumps(scenario, sort_keys=True)),
    )
    return Path(write_bytes_atomic(path, buffer.getvalue()))


def read_vertices(path: str | os.PathLike, rig) -> tuple[np.ndarray, float]:
    """``(F, V, 3)`` world vertices (cm) of ``rig``'s every vertex, and the fps, from a
    simulation file (or any joint-tracks npz naming the rig's vertices); refused with one
    line when a vertex is missing or extra, or a position is not a finite number."""
    tracks = read_tracks(path, unit="cm")
    names = tuple(rig.joint_names)
    if len(tracks.joint_names) != len(names):
        raise VertexInputError(
            f"{path}: {len(tracks.joint_names)} vertices per frame, rig {rig.name!r} has "
            f"{len(names)}"
        )
    if set(tracks.joint_names) != set(names):
        unknown = sorted(set(tracks.joint_names) - set(names))[:5]
        raise VertexInputError(f"{path}: vertices {unknown} are not rig {rig.name!r}'s")
    return tracks.subset(names).positions, float(tracks.fps)
