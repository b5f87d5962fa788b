"""The ``animate`` and ``pose`` stages: Hydra wiring, determinism, DVC matrix, held-out tests."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from scipy.spatial import cKDTree

from rigmap.animation.corpus import Corpus
from rigmap.animation.posing import PoseTable
from rigmap.rigs import load
from stage_scripts import load_stage as _stage

ROOT = Path(__file__).resolve().parents[1]
_RUNS: dict = {}


def config(*overrides: str):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def stages_run(tmp_path_factory, rig: str, seed: int = 0) -> Path:
    """Both stages for one rig into a fresh data folder, once per session."""
    if (rig, seed) not in _RUNS:
        data = tmp_path_factory.mktemp(f"{rig}_{seed}")
        cfg = config(f"rig={rig}", f"seed={seed}", f"paths.data={data}")
        _stage("animate").run(cfg)
        _stage("pose").run(cfg, progress=False)
        _RUNS[rig, seed] = data
    return _RUNS[rig, seed]


def test_config_composes_every_rig_with_corpus_options():
    for rig in ("quadruped", "biped", "face", "squirrel"):
        cfg = config(f"rig={rig}")
        assert cfg.rig.name == rig
        assert cfg.rig.corpus.fps in (24, 30)
        assert cfg.paths.data == "data" and cfg.seed == 0
    assert config("experiment=paper").corpus.variation == 1.0


def test_same_seed_gives_byte_identical_files_another_seed_does_not(tmp_path, tmp_path_factory):
    first = stages_run(tmp_path_factory, "face")
    again = tmp_path / "again"
    _stage("animate").run(config("rig=face", f"paths.data={again}"))
    other = tmp_path / "other"
    _stage("animate").run(config("rig=face", "seed=7", f"paths.data={other}"))
    for split in ("train", "test"):
        name = f"face/corpus/{split}.parquet"
        assert (first / name).read_bytes() == (again / name).read_bytes()
        assert (first / name).read_bytes() != (other / name).read_bytes()
    meta = Corpus.read(first / "face/corpus/train.parquet").metadata
    assert (meta["rig"], meta["fps"], meta["seed"]) == ("face", 30, 0)


def test_pose_stage_output_matches_the_rig_on_the_corpus(tmp_path_factory):
    data = stages_run(tmp_path_factory, "biped")
    rig = load("biped")
    for split in ("train", "test"):
        corpus = Corpus.read(data / f"biped/corpus/{split}.parquet", rig="biped", split=split)
        poses = PoseTable.read(data / f"biped/poses/{split}.parquet", rig="biped", n_joints=73)
        rows = np.arange(0, len(corpus.table), 7)
        expected = rig.pose(rig.expand_used(corpus.values()[rows]))
        np.testing.assert_allclose(poses.positions()[rows], expected.positions, atol=1e-12)
        np.testing.assert_allclose(poses.cog()[rows], expected.cog, atol=1e-12)
        assert poses.metadata["corpus"]["source"].endswith(f"biped/corpus/{split}.parquet")


def _mean_nearest(points: np.ndarray, reference: np.ndarray) -> float:
    return float(cKDTree(reference).query(points)[0].mean())


@pytest.mark.parametrize(
    "rig_name",
    ["quadruped", "biped", "face", pytest.param("squirrel", marks=pytest.mark.slow)],
)
def test_test_clips_lie_farther_from_training_than_held_out_training_clips(
    rig_name, tmp_path_factory, record_property
):
    """Mean nearest-neighbour distance in joint space (COG-relative, cm): test frames to
    training frames, against each training clip held out in turn to the other clips."""
    data = stages_run(tmp_path_factory, rig_name)
    train = PoseTable.read(data / f"{rig_name}/poses/train.parquet")
    test = PoseTable.read(data / f"{rig_name}/poses/test.parquet")
    X, T = train.flat_positions(), test.flat_positions()
    clips = train.table["clip"].to_numpy()
    test_to_train = _mean_nearest(T, X)
    held_out = np.concatenate(
        [cKDTree(X[clips != c]).query(X[clips == c])[0] for c in np.unique(clips)]
    ).mean()
    print(
        f"\n{rig_name}: mean nearest-neighbour distance (cm) test->train {test_to_train:.2f}, "
        f"held-out train clip->other train clips {held_out:.2f}"
    )
    record_property(f"{rig_name}_nn_test_to_train_cm", round(test_to_train, 3))
    record_property(f"{rig_name}_nn_heldout_train_cm", round(float(held_out), 3))
    assert test_to_train > 1.5 * held_out


def test_hydra_entry_point_writes_only_the_declared_outputs(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    result = subprocess.run(
        [sys.executable, str(ROOT / "pipelines/animate.py"), "rig=face", "paths.data=data"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "face train:" in result.stdout
    written = sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())
    assert written == ["data/face/corpus/test.parquet", "data/face/corpus/train.parquet"]


def test_a_rig_without_a_motion_library_is_a_clear_error(tmp_path):
    """Refused before the rig is built (a Blender rig would start worker processes): a
    user's own .blend rig (registered as ``blend_file``) comes with no motion library."""
    cfg = config("rig=rigify_human", "rig.name=blend_file", f"paths.data={tmp_path}")
    with pytest.raises(KeyError, match="no motion library for rig 'blend_file'"):
        _stage("animate").run(cfg)
    assert not any(tmp_path.iterdir())
