"""Poses tables: the rig on every corpus frame, written and read back with validation."""

from __future__ import annotations

import json
import re

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from rigmap.animation.library import build_corpus
from rigmap.animation.posing import (
    COG_COLUMNS,
    COG_ROTATION_COLUMNS,
    PosesError,
    PoseTable,
    joint_columns,
    pose_corpus,
)
from rigmap.rigs import load

_CACHE: dict = {}


def posed(rig_name: str, split: str = "test"):
    """(rig, corpus, poses) for a built-in rig, built once per session."""
    if (rig_name, split) not in _CACHE:
        rig = load(rig_name)
        corpus = build_corpus(rig, split, seed=0)
        _CACHE[rig_name, split] = (rig, corpus, pose_corpus(rig, corpus, batch_size=100))
    return _CACHE[rig_name, split]


def test_poses_match_the_rig_on_the_corpus():
    rig, corpus, poses = posed("quadruped")
    Y = rig.expand_used(corpus.values())
    expected = rig.pose(Y)
    np.testing.assert_allclose(poses.positions(), expected.positions, atol=1e-12)
    np.testing.assert_allclose(poses.cog(), expected.cog, atol=1e-12)
    np.testing.assert_allclose(poses.cog_rotation(), expected.cog_rotation, atol=1e-12)
    assert poses.flat_positions().shape == (len(corpus.table), 3 * rig.n_joints)
    assert list(poses.table["clip"]) == list(corpus.table["clip"])
    assert list(poses.table["frame"]) == list(corpus.table["frame"])
    # world positions come back by adding the COG
    world = poses.positions() + poses.cog()[:, None, :]
    assert world[:, :, 1].min() > -5.0  # cm: nothing sinks far into the ground


def test_columns_and_metadata():
    rig, corpus, poses = posed("face")
    assert list(poses.table.columns) == [
        "clip", "frame", *joint_columns(rig.joint_names), *COG_COLUMNS, *COG_ROTATION_COLUMNS,
    ]  # fmt: skip
    assert poses.table.shape[1] == 2 + 3 * 6 + 3 + 9
    meta = poses.metadata
    assert meta["rig"] == "face" and meta["split"] == "test" and meta["seed"] == 0
    assert meta["joint_names"] == rig.joint_names
    assert meta["parents"] is None  # a mesh rig
    assert [c["name"] for c in meta["clips"]] == corpus.clip_names
    assert meta["corpus"]["key_count"] == corpus.key_count


def test_round_trip_is_exact_and_deterministic(tmp_path):
    _, _, poses = posed("quadruped")
    a = poses.write(tmp_path / "a.parquet")
    b = poses.write(tmp_path / "b.parquet")
    assert a.read_bytes() == b.read_bytes()
    back = PoseTable.read(a, rig="quadruped", n_joints=76, split="test")
    np.testing.assert_array_equal(back.positions(), poses.positions())
    np.testing.assert_array_equal(back.cog_rotation(), poses.cog_rotation())
    assert back.metadata == poses.metadata
    assert not list(tmp_path.glob(".*.tmp"))  # no temp files left behind


def _rewrite(path, table, metadata):
    """Write a table with given metadata straight through pyarrow (bypassing the checks)."""
    arrow = pa.Table.from_pandas(table, preserve_index=False)
    arrow = arrow.replace_schema_metadata({b"rigmap": json.dumps(metadata).encode()})
    pq.write_table(arrow, path)
    return path


def test_nan_positions_are_refused_naming_file_column_clip_and_frame(tmp_path):
    _, _, poses = posed("quadruped")
    table = poses.table.copy()
    table.loc[7, "hind_paw_l.y"] = np.nan
    path = _rewrite(tmp_path / "nan.parquet", table, poses.metadata)
    clip, frame = table["clip"].iloc[7], table["frame"].iloc[7]
    with pytest.raises(PosesError) as error:
        PoseTable.read(path)
    message = str(error.value)
    assert str(path) in message and "'hind_paw_l.y'" in message
    assert f"clip {clip!r}" in message and f"frame {frame}" in message
    table.loc[7, "hind_paw_l.y"] = np.inf
    with pytest.raises(PosesError, match=r"'hind_paw_l\.y' is inf"):
        PoseTable(table, poses.metadata).write(tmp_path / "inf.parquet")
    assert not (tmp_path / "inf.parquet").exists()


def test_wrong_joint_count_is_refused(tmp_path):
    _, _, poses = posed("quadruped")
    path = poses.write(tmp_path / "poses.parquet")
    with pytest.raises(PosesError, match=r"76 joints, expected 73 \(rig 'quadruped'\)"):
        PoseTable.read(path, n_joints=73)
    with pytest.raises(PosesError, match="poses are for rig 'quadruped', expected 'biped'"):
        PoseTable.read(path, rig="biped")
    dropped = poses.table.drop(columns=["tail_tip.x", "tail_tip.y", "tail_tip.z"])
    broken = _rewrite(tmp_path / "dropped.parquet", dropped, poses.metadata)
    with pytest.raises(PosesError) as error:
        PoseTable.read(broken)
    message = str(error.value)
    assert str(broken) in message
    assert "228 position columns expected, 225 found" in message
    assert "tail_tip.x" in message


def test_files_that_are_not_poses(tmp_path):
    _, corpus, _ = posed("quadruped")
    corpus_file = corpus.write(tmp_path / "corpus.parquet")
    with pytest.raises(
        PosesError, match=re.escape("format 'rigmap.corpus/1', expected 'rigmap.poses/1'")
    ):
        PoseTable.read(corpus_file)
    with pytest.raises(FileNotFoundError, match=r"missing\.parquet does not exist"):
        PoseTable.read(tmp_path / "missing.parquet")
    (tmp_path / "junk.parquet").write_bytes(b"not parquet at all")
    with pytest.raises(PosesError, match=r"junk\.parquet: not a readable parquet file"):
        PoseTable.read(tmp_path / "junk.parquet")


def test_a_corpus_for_another_rig_is_refused():
    _, corpus, _ = posed("quadruped")
    with pytest.raises(PosesError, match="corpus is for rig 'quadruped', but the rig is 'biped'"):
        pose_corpus(load("biped"), corpus)
