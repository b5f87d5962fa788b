"""The ``supersample`` and ``sample_figures`` stages: Hydra wiring, resuming, DVC matrix, Fig. 4."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from rigmap.animation.corpus import Corpus
from rigmap.sampling import available, load_samples
from stage_scripts import load_stage as _stage

ROOT = Path(__file__).resolve().parents[1]
N = 300
RIGS = ["quadruped", "biped", "face", "squirrel"]


def config(*overrides: str):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


def corpus_copy(folder: Path, rig: str) -> Path:
    """A data folder holding the rig's train corpus (built by the animate stage if missing)."""
    source = ROOT / "data" / rig / "corpus" / "train.parquet"
    if source.is_file():
        (folder / rig / "corpus").mkdir(parents=True)
        shutil.copy(source, folder / rig / "corpus" / "train.parquet")
    else:
        _stage("animate").run(config(f"rig={rig}", f"paths.data={folder}"))
    return folder


@pytest.fixture
def quadruped_data(tmp_path) -> Path:
    return corpus_copy(tmp_path / "data", "quadruped")


def train_controls(data: Path, rig) -> np.ndarray:
    path = data / rig.name / "corpus" / "train.parquet"
    return Corpus.read(path, rig=rig.name, control_names=rig.used_controls).values()


def test_stage_writes_the_samples_and_the_rigs_poses_of_them(quadruped, quadruped_data, capsys):
    stage = _stage("supersample")
    cfg = config(
        "rig=quadruped",
        "sampler=pca_gaussian",
        f"budget.samples={N}",
        f"paths.data={quadruped_data}",
    )
    result = stage.run(cfg, progress=False)

    path = quadruped_data / "quadruped" / "samples" / "pca_gaussian.npz"
    assert result.path == path and result.n_samples == N
    samples = load_samples(path)
    n_used = len(quadruped.used_controls)
    assert samples["controls"].shape == (N, n_used)
    assert samples["positions"].shape == (N, quadruped.n_joints, 3)
    assert samples["cog"].shape == (N, 3) and samples["cog_rotation"].shape == (N, 3, 3)
    pose = quadruped.pose(quadruped.expand_used(samples["controls"]))
    np.testing.assert_allclose(samples["positions"], pose.positions, rtol=0, atol=1e-9)
    np.testing.assert_allclose(samples["cog"], pose.cog, rtol=0, atol=1e-9)
    np.testing.assert_allclose(samples["cog_rotation"], pose.cog_rotation, rtol=0, atol=1e-12)

    # the samples are the configured strategy's, fitted on the train corpus and seeded
    meta = samples["meta"]
    assert (meta["rig"], meta["sampler"], meta["n_samples"]) == ("quadruped", "pca_gaussian", N)
    assert meta["seed"] == stage.sampler_seed(0, "pca_gaussian")
    sampler = stage.sampler_from_config(cfg.sampler, quadruped)
    sampler.fit(train_controls(quadruped_data, quadruped))
    drawn = sampler.sample(N, np.random.default_rng(meta["seed"]))
    used = quadruped.controls.used_indices
    lower, upper = quadruped.controls.lower[used], quadruped.controls.upper[used]
    np.testing.assert_array_equal(samples["controls"], np.clip(drawn, lower, upper))
    clamped = int(((drawn < lower) | (drawn > upper)).sum())
    assert clamped > 0 and int(samples["n_clamped"]) == clamped == result.n_clamped
    assert f"clamped {clamped} of {N * n_used} control values" in capsys.readouterr().out
    assert [p.name for p in path.parent.iterdir()] == ["pca_gaussian.npz"]


def test_samplers_draw_from_different_seeds_and_uniform_soft_uses_the_rigs_range(tmp_path):
    stage = _stage("supersample")
    seeds = {name: stage.sampler_seed(0, name) for name in available()}
    assert len(set(seeds.values())) == len(seeds)
    assert seeds["gmm"] == stage.sampler_seed(0, "gmm") != stage.sampler_seed(1, "gmm")

    data = corpus_copy(tmp_path, "face")
    cfg = config(
        "rig=face",
        "sampler=uniform",
        "sampler.range=soft",
        "budget.samples=2000",
        f"paths.data={data}",
    )
    stage.run(cfg, progress=False)
    samples = load_samples(data / "face" / "samples" / "uniform.npz")
    rig = _stage("animate").rig_from_config(cfg.rig)
    used = rig.controls.used_indices
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    corpus = train_controls(data, rig)
    assert samples["meta"]["sampler_params"]["lower"] == lower.tolist()
    assert samples["meta"]["sampler_params"]["upper"] == upper.tolist()
    Y = samples["controls"]
    assert (Y >= lower).all() and (Y <= upper).all() and int(samples["n_clamped"]) == 0
    # soft, not corpus range: some control is drawn beyond what the animators used
    assert (Y.max(axis=0) > corpus.max(axis=0) + 1e-9).any()
    width = upper - lower
    assert np.all(Y.min(axis=0) - lower < 0.05 * width)
    assert np.all(upper - Y.max(axis=0) < 0.05 * width)


KILLABLE_STAGE = """
import runpy, sys, time
sys.path.insert(0, {pipelines!r})
import rigmap.app.inputs as stage_inputs

class SlowRig:
    # the real rig, posing slowly enough that the test can kill the run between chunks
    def __init__(self, rig):
        self._rig = rig
    def __getattr__(self, name):
        return getattr(self._rig, name)
    def pose(self, Y):
        time.sleep(0.4)
        return self._rig.pose(Y)

real = stage_inputs.rig_from_config
stage_inputs.rig_from_config = lambda *args: SlowRig(real(*args))  # what the stage imports
sys.argv = [{stage!r}, *{overrides!r}]
runpy.run_path({stage!r}, run_name="__main__")
"""


@pytest.mark.slow
def test_a_killed_stage_resumes_from_its_chunks_to_the_same_file(tmp_path):
    # the face: quick to load in a fresh process; the slowed rig makes the chunks last
    data = corpus_copy(tmp_path / "data", "face")
    overrides = [
        "rig=face",
        "sampler=pca_gaussian",
        f"budget.samples={N}",
        "supersample.chunk_size=50",  # 6 chunks
        f"paths.data={data}",
        "seed=3",
    ]
    samples = data / "face" / "samples"
    target, chunks = samples / "pca_gaussian.npz", samples / "pca_gaussian.chunks"
    script = KILLABLE_STAGE.format(
        pipelines=str(ROOT / "pipelines"),
        stage=str(ROOT / "pipelines" / "supersample.py"),
        overrides=overrides,
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    process = subprocess.Popen(
        [sys.executable, "-c", script], env=env, cwd=ROOT, stderr=subprocess.PIPE
    )
    try:
        deadline = time.monotonic() + 120
        while not list(chunks.glob("chunk_*.npz")):
            assert process.poll() is None, process.stderr.read().decode()[-2000:]
            assert time.monotonic() < deadline, "the stage never finished its first chunk"
            time.sleep(0.02)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    assert process.returncode == -signal.SIGKILL
    finished = len(list(chunks.glob("chunk_*.npz")))
    assert 1 <= finished < 6 and not target.exists()

    stage = _stage("supersample")
    resumed = stage.run(config(*overrides), progress=False)
    assert (resumed.chunks_resumed, resumed.chunks_evaluated) == (finished, 6 - finished)
    assert not chunks.exists()

    whole = corpus_copy(tmp_path / "whole", "face")
    uninterrupted = [o for o in overrides if not o.startswith("paths.data")]
    result = stage.run(config(*uninterrupted, f"paths.data={whole}"), progress=False)
    assert result.chunks_evaluated == 6
    assert target.read_bytes() == (whole / "face/samples/pca_gaussian.npz").read_bytes()


def test_sample_figure_has_one_row_per_strategy(quadruped, quadruped_data, tmp_path):
    supersample, figures = _stage("supersample"), _stage("sample_figures")
    data = quadruped_data
    for name in available():
        # a small diagonal mixture keeps this fast; the stage's GMM is tested in test_sampling
        small = ["sampler.n_components=3", "sampler.covariance_type=diag"] if name == "gmm" else []
        overrides = ["rig=quadruped", f"sampler={name}", "budget.samples=40", *small]
        supersample.run(config(*overrides, f"paths.data={data}"), progress=False)
    reports = tmp_path / "reports"
    figure = figures.run(
        config(
            "rig=quadruped", f"paths.data={data}", f"paths.reports={reports}", "figures.per_row=3"
        )
    )

    assert figure.path == reports / "figures" / "samples_quadruped.png"
    assert figure.view == "side"
    strategies = [row.strategy for row in figure.rows]
    assert strategies == available()  # the corpus row stands for "none", then Table 2's order
    corpus = train_controls(data, quadruped)
    np.testing.assert_array_equal(figure.rows[0].controls, corpus[figure.rows[0].indices])
    for row in figure.rows[1:]:
        stored = load_samples(data / "quadruped" / "samples" / f"{row.strategy}.npz")
        assert len(row.indices) == 3 and len(set(row.indices.tolist())) == 3
        np.testing.assert_array_equal(row.positions, stored["positions"][row.indices])
        np.testing.assert_array_equal(row.controls, stored["controls"][row.indices])

    import matplotlib.image

    image = matplotlib.image.imread(figure.path)
    assert image.shape[0] > image.shape[1]  # six rows of three poses
    # every row drew something: dark skeleton pixels in each band, right of the row titles
    panels = image[int(0.08 * len(image)) :, image.shape[1] // 2 :, :3].mean(axis=2)
    bands = np.array_split(panels, len(figure.rows))
    assert all((band < 0.5).sum() > 50 for band in bands)
    assert [p.name for p in (reports / "figures").iterdir()] == ["samples_quadruped.png"]


def test_figure_stage_names_the_missing_samples_file(tmp_path):
    data = corpus_copy(tmp_path, "face")
    with pytest.raises(
        FileNotFoundError, match=r"face/samples/none\.npz does not exist.*sampler=none"
    ):
        _stage("sample_figures").run(config("rig=face", f"paths.data={data}"))
