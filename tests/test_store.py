"""rigmap.store: paths, model ids, atomic files and folders, table files, plain JSON."""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
import pytest

from rigmap.store import (
    Layout,
    ModelId,
    TableFileError,
    atomic_file,
    json_ready,
    read_table_file,
    write_folder_atomic,
    write_json_atomic,
    write_table_file,
    write_text_atomic,
)


def test_model_id_round_trips_through_its_folder_name():
    model = ModelId("nn", "pca_gaussian")
    assert model.folder_name == "nn-pca_gaussian-none"
    assert ModelId.parse(model.folder_name) == model
    assert ModelId.parse("gpr-none-multiquadric").kernel == "multiquadric"


@pytest.mark.parametrize("bad", ["gpr-none", "a-b-c-d", "GPR-none-x", "nn-../x-none"])
def test_model_id_rejects_names_that_are_not_folder_safe(bad):
    with pytest.raises(ValueError, match="model"):
        ModelId.parse(bad)


def test_layout_paths_follow_the_roots():
    layout = Layout.from_paths({"data": "d", "models": "m"})
    assert layout.corpus("biped", "train") == layout.data / "biped/corpus/train.parquet"
    assert str(layout.poses("face", "test")) == "d/face/poses/test.parquet"
    assert str(layout.samples("quadruped", "gmm")) == "d/quadruped/samples/gmm.npz"
    assert str(layout.model("biped", ModelId("gpr", kernel="linear"))) == "m/biped/gpr-none-linear"
    assert str(layout.metrics_folder("biped", "methods")) == "metrics/biped/methods"
    with pytest.raises(ValueError, match="split 'valid'"):
        layout.corpus("biped", "valid")
    with pytest.raises(ValueError, match="unknown keys"):
        Layout.from_paths({"dta": "x"})


def test_atomic_file_leaves_the_old_file_when_the_writer_fails(tmp_path):
    target = tmp_path / "out.txt"
    write_text_atomic(target, "old")
    with pytest.raises(RuntimeError), atomic_file(target) as temporary:
        temporary.write_text("half")
        raise RuntimeError("killed")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]
    assert oct(os.stat(target).st_mode & 0o777) == "0o644"


def test_write_json_atomic_is_strict(tmp_path):
    path = write_json_atomic(tmp_path / "a.json", {"b": 1, "a": [1.5]})
    assert json.loads(path.read_text()) == {"a": [1.5], "b": 1}
    with pytest.raises(ValueError):
        write_json_atomic(tmp_path / "nan.json", {"x": float("nan")})
    assert not (tmp_path / "nan.json").exists()


def test_folder_is_replaced_only_when_complete(tmp_path):
    folder = tmp_path / "model"
    write_folder_atomic(folder, lambda staging: (staging / "a").write_text("1"))

    def broken(staging):
        (staging / "a").write_text("2")
        raise OSError("disk full")

    with pytest.raises(OSError):
        write_folder_atomic(folder, broken)
    assert (folder / "a").read_text() == "1"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"]


def test_table_file_round_trip_is_byte_deterministic(tmp_path):
    table = pd.DataFrame({"clip": ["a", "a"], "x": [1.0, 2.0]})
    meta = {"format": "t/1", "rig": "biped"}
    first = write_table_file(tmp_path / "one.parquet", table, b"rigmap.test", meta)
    second = write_table_file(tmp_path / "two.parquet", table, b"rigmap.test", meta)
    assert first.read_bytes() == second.read_bytes()
    read, read_meta = read_table_file(first, b"rigmap.test")
    pd.testing.assert_frame_equal(read, table)
    assert read_meta == meta
    with pytest.raises(TableFileError, match=r"no 'rigmap\.other' metadata"):
        read_table_file(first, b"rigmap.other")
    (tmp_path / "junk.parquet").write_bytes(b"not parquet")
    with pytest.raises(TableFileError, match=r"junk\.parquet: not a readable parquet"):
        read_table_file(tmp_path / "junk.parquet", b"rigmap.test")


def test_json_ready_gives_plain_numbers():
    data = {"a": np.float32(1.5), "b": np.arange(2), "c": (np.int64(3), float("inf"))}
    assert json_ready(data) == {"a": 1.5, "b": [0, 1], "c": [3, None]}
    assert json_ready(float("nan"), nonfinite_to_null=False) != json_ready(float("nan"))
