"""Poses: the rig evaluated on every frame of a corpus, as parquet (the ``pose`` stage).

The inverse mapping learns from pairs (joint positions, controls). This module runs
the rig function ``f`` over a corpus table and stores what it gives: per frame the
joint positions relative to the centre of gravity (§3.2) and the COG's own world
placement, from which root controls can be recovered.

Columns: ``clip``, ``frame``, then ``<joint>.x``, ``<joint>.y``, ``<joint>.z`` for
every joint in rig order (cm, COG-relative), then ``cog.x``/``cog.y``/``cog.z`` (cm,
world) and ``cog_rot.00`` .. ``cog_rot.22`` (the COG's world rotation matrix, row by
row). The parquet schema metadata (key ``rigmap``) holds the rig, split, seed, frame
rate, joint names, the clips' frame ranges and the corpus it came from. Files are
written atomically and deterministically; reading checks shapes and finiteness and
names the file, column, clip and frame of anything wrong.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.animation.corpus import KEY_COLUMNS, Corpus, misplaced_clip
from rigmap.errors import RigmapError
from rigmap.store import read_table_file, write_table_file

POSES_FORMAT = "rigmap.poses/1"
METADATA_KEY = b"rigmap"
AXES = ("x", "y", "z")
COG_COLUMNS = tuple(f"cog.{a}" for a in AXES)
COG_ROTATION_COLUMNS = tuple(f"cog_rot.{r}{c}" for r in range(3) for c in range(3))
DEFAULT_BATCH = 512


class PosesError(RigmapError, ValueError):
    """A poses table that cannot be built, or a file that is not a valid poses file."""


def joint_columns(joint_names: Sequence[str]) -> list[str]:
    """``<joint>.x/.y/.z`` for every joint, in order."""
    return [f"{name}.{axis}" for name in joint_names for axis in AXES]


@dataclass
class PoseTable:
    """Joint positions and COG placement per corpus frame, with their metadata."""

    table: pd.DataFrame
    metadata: dict = field(default_factory=dict)

    @property
    def joint_names(self) -> list[str]:
        return list(self.metadata["joint_names"])

    @property
    def n_joints(self) -> int:
        return len(self.metadata["joint_names"])

    @property
    def clip_names(self) -> list[str]:
        return [c["name"] for c in self.metadata["clips"]]

    def positions(self) -> np.ndarray:
        """``(N, J, 3)`` joint positions relative to the COG (cm)."""
        flat = self.table[joint_columns(self.joint_names)].to_numpy(dtype=np.float64)
        return flat.reshape(len(flat), self.n_joints, 3)

    def flat_positions(self) -> np.ndarray:
        """``(N, 3J)``: the regression input ``x`` of §3.2."""
        return self.table[joint_columns(self.joint_names)].to_numpy(dtype=np.float64)

    def cog(self) -> np.ndarray:
        """``(N, 3)`` COG world positions (cm)."""
        return self.table[list(COG_COLUMNS)].to_numpy(dtype=np.float64)

    def cog_rotation(self) -> np.ndarray:
        """``(N, 3, 3)`` COG world rotations."""
        flat = self.table[list(COG_ROTATION_COLUMNS)].to_numpy(dtype=np.float64)
        return flat.reshape(len(flat), 3, 3)

    def write(self, path: str | os.PathLike) -> Path:
        return write_poses(path, self.table, self.metadata)

    @classmethod
    def read(
        cls,
        path: str | os.PathLike,
        *,
        rig: str | None = None,
        n_joints: int | None = None,
        split: str | None = None,
    ) -> PoseTable:
        table, metadata = read_poses(path, rig=rig, n_joints=n_joints, split=split)
        return cls(table, metadata)


def pose_corpus(
    rig,
    corpus: Corpus,
    *,
    batch_size: int = DEFAULT_BATCH,
    progress: bool = False,
    source: str | None = None,
) -> PoseTable:
    """Evaluate ``rig`` on every frame of ``corpus`` (its used-control columns).

    Controls the corpus does not hold stay at the rig's defaults. ``source`` names
    the corpus file in the metadata.
    """
    if corpus.rig != rig.name:
        raise PosesError(f"corpus is for rig {corpus.rig!r}, but the rig is {rig.name!r}")
    unknown = [c for c in corpus.controls if c not in rig.controls]
    if unknown:
        raise PosesError(f"corpus controls not on rig {rig.name!r}: {unknown[:10]}")
    if batch_size < 1:
        raise ValueError(f"batch_size must be >= 1, got {batch_size}")
    clashing = [n for n in rig.joint_names if f"{n}.x" in (*COG_COLUMNS, *KEY_COLUMNS)]
    if clashing or rig.n_joints == 0:
        raise PosesError(
            f"rig {rig.name!r}: joint names {clashing} clash with the columns "
            f"{(*KEY_COLUMNS, *COG_COLUMNS)}"
            if clashing
            else f"rig {rig.name!r} has no joints"
        )
    values = corpus.values()
    columns = [rig.controls.index(c) for c in corpus.controls]
    positions = np.empty((len(values), rig.n_joints, 3))
    cog = np.empty((len(values), 3))
    cog_rotation = np.empty((len(values), 3, 3))
    starts = range(0, len(values), batch_size)
    if progress:
        from tqdm import tqdm

        starts = tqdm(starts, desc=f"posing {rig.name} {corpus.split}", unit="batch")
    for start in starts:
        rows = slice(start, start + batch_size)
        Y = rig.default_controls(len(values[rows]))
        Y[:, columns] = values[rows]
        pose = rig.pose(Y)
        positions[rows] = np.asarray(pose.positions, dtype=np.float64)
        cog[rows] = np.asarray(pose.cog, dtype=np.float64)
        cog_rotation[rows] = np.asarray(pose.cog_rotation, dtype=np.float64)
    table = poses_table(
        corpus.table["clip"].to_numpy(),
        corpus.table["frame"].to_numpy(),
        positions,
        cog,
        cog_rotation,
        rig.joint_names,
    )
    metadata = {
        "format": POSES_FORMAT,
        "rig": rig.name,
        "split": corpus.split,
        "seed": corpus.metadata.get("seed"),
        "fps": corpus.fps,
        "length_unit": getattr(rig, "length_unit", "cm"),
        "joint_names": list(rig.joint_names),
        "parents": None if rig.parents is None else [int(p) for p in rig.parents],
        "clips": [
            {k: c[k] for k in ("name", "start", "end", "frames")} for c in corpus.metadata["clips"]
        ],
        "frame_count": len(table),
        "corpus": {
            "source": source,
            "frame_count": len(corpus.table),
            "key_count": corpus.key_count,
            "controls": len(corpus.controls),
        },
    }
    return PoseTable(table, metadata)


def poses_table(
    clips: Sequence[str],
    frames: Sequence[int],
    positions: np.ndarray,
    cog: np.ndarray,
    cog_rotation: np.ndarray,
    joint_names: Sequence[str],
) -> pd.DataFrame:
    """Assemble the columns (see the module docstring) from arrays."""
    n = len(frames)
    positions = np.asarray(positions, dtype=np.float64)
    if positions.shape != (n, len(joint_names), 3):
        raise PosesError(
            f"positions must have shape ({n}, {len(joint_names)}, 3), got {positions.shape}"
        )
    blocks = [
        pd.DataFrame(
            {"clip": np.asarray(clips).astype(str), "frame": np.asarray(frames, np.int64)}
        ),
        pd.DataFrame(positions.reshape(n, -1), columns=joint_columns(joint_names)),
        pd.DataFrame(np.asarray(cog, np.float64).reshape(n, 3), columns=list(COG_COLUMNS)),
        pd.DataFrame(
            np.asarray(cog_rotation, np.float64).reshape(n, 9), columns=list(COG_ROTATION_COLUMNS)
        ),
    ]
    return pd.concat(blocks, axis=1)


# --- files ------------------------------------------------------------------------------
def write_poses(path: str | os.PathLike, table: pd.DataFrame, metadata: Mapping) -> Path:
    """Write atomically (:func:`rigmap.store.write_table_file`); same input, same bytes."""
    _check_table(table, metadata, source="poses table to write")
    return write_table_file(path, table, METADATA_KEY, metadata, error=PosesError, what="poses")


def read_poses(
    path: str | os.PathLike,
    *,
    rig: str | None = None,
    n_joints: int | None = None,
    split: str | None = None,
) -> tuple[pd.DataFrame, dict]:
    """Read a poses file and check it (and, when given, its rig, joint count and split)."""
    path = Path(path)
    table, metadata = read_table_file(path, METADATA_KEY, error=PosesError, what="poses")
    if metadata.get("format") != POSES_FORMAT:
        raise PosesError(f"{path}: format {metadata.get('format')!r}, expected {POSES_FORMAT!r}")
    for name, wanted in (("rig", rig), ("split", split)):
        if wanted is not None and metadata.get(name) != wanted:
            raise PosesError(
                f"{path}: poses are for {name} {metadata.get(name)!r}, expected {wanted!r}"
            )
    if n_joints is not None and len(metadata.get("joint_names", [])) != n_joints:
        raise PosesError(
            f"{path}: {len(metadata.get('joint_names', []))} joints, expected {n_joints} "
            f"(rig {metadata.get('rig')!r})"
        )
    _check_table(table, metadata, source=str(path))
    return table, metadata


def _check_table(table: pd.DataFrame, metadata: Mapping, source: str) -> None:
    """Columns match the joint names in the metadata, numbers are finite, clips line up."""
    for key in ("joint_names", "clips", "rig", "split"):
        if key not in metadata:
            raise PosesError(f"{source}: poses metadata lacks {key!r}")
    joints = list(metadata["joint_names"])
    expected = [*KEY_COLUMNS, *joint_columns(joints), *COG_COLUMNS, *COG_ROTATION_COLUMNS]
    if list(table.columns) != expected:
        position_columns = [
            c for c in table.columns if c.rsplit(".", 1)[-1] in AXES and c not in COG_COLUMNS
        ]
        found = len(position_columns) / 3
        missing = [c for c in expected if c not in table.columns]
        unexpected = [c for c in table.columns if c not in expected]
        raise PosesError(
            f"{source}: columns do not match the metadata's {len(joints)} joints "
            f"({3 * len(joints)} position columns expected, {len(position_columns)} found, "
            f"i.e. {found:g} joints): missing {missing[:6]}, unexpected {unexpected[:6]}"
        )
    if len(table) == 0:
        raise PosesError(f"{source}: the poses table is empty (no rows)")
    numbers = expected[len(KEY_COLUMNS) :]
    values = table[numbers].to_numpy(dtype=np.float64)
    finite = np.isfinite(values)
    if not finite.all():
        row, col = np.argwhere(~finite)[0]
        raise PosesError(
            f"{source}: column {numbers[col]!r} is {values[row, col]} at clip "
            f"{table['clip'].iloc[row]!r}, frame {table['frame'].iloc[row]}; joint positions "
            "and COG placement must be finite numbers"
        )
    clip, row = misplaced_clip(table, metadata["clips"])
    if clip is not None:
        raise PosesError(
            f"{source}: clip {clip['name']!r}: expected frames {clip['start']}..{clip['end']} "
            f"({clip['frames']} rows) from row {row}; the table does not hold them there"
        )
    if row != len(table):
        raise PosesError(f"{source}: {len(table) - row} rows after the last clip in the metadata")
