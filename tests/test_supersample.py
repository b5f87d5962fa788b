"""The resumable supersampling runner on the quadruped: draw, clamp, pose, save, resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rigmap.sampling import (
    NoExtraSamples,
    PCAGaussianSampler,
    SamplerInputError,
    SamplerNotFittedError,
    UnivariateGaussianSampler,
    available,
    make_sampler,
    supersample,
)
from rigmap.sampling.supersample import SupersampleError, load_samples

N = 450
CHUNK = 100  # -> 5 chunks, the last one short
N_CHUNKS = 5


class Killed(Exception):
    """Stands in for the process being killed between two chunks."""


class WatchedRig:
    """Delegates to a real rig, counts ``pose`` calls and can die after ``fail_after`` calls."""

    def __init__(self, rig, fail_after: int | None = None, corrupt: bool = False):
        self._rig = rig
        self._fail_after = fail_after
        self._corrupt = corrupt
        self.calls = 0

    def __getattr__(self, name):
        return getattr(self._rig, name)

    def pose(self, Y):
        if self._fail_after is not None and self.calls >= self._fail_after:
            raise Killed(f"killed before chunk {self.calls}")
        self.calls += 1
        pose = self._rig.pose(Y)
        if self._corrupt:
            positions = pose.positions.copy()
            positions[7, 3, 1] = np.nan
            pose = pose._replace(positions=positions)
        return pose


class SlowRig(WatchedRig):
    """Poses slowly enough that a test can kill the process between chunks."""

    def pose(self, Y):
        time.sleep(0.25)
        return super().pose(Y)


def quadruped_corpus(rig) -> np.ndarray:
    """Correlated motion of the used controls around their defaults (radians, cm)."""
    rng = np.random.default_rng(0)
    used = rig.controls.used_indices
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    mixing = rng.normal(size=(6, used.size)) * 0.08 * (upper - lower)
    motion = rig.controls.defaults[used] + rng.normal(size=(300, 6)) @ mixing
    return np.clip(motion, lower, upper)


@pytest.fixture(scope="module")
def corpus(quadruped) -> np.ndarray:
    return quadruped_corpus(quadruped)


@pytest.fixture(scope="module")
def sampler(corpus) -> PCAGaussianSampler:
    return PCAGaussianSampler().fit(corpus)


def run(rig, sampler, folder, **options):
    options = {"seed": 11, "chunk_size": CHUNK, "progress": False, **options}
    return supersample(rig, sampler, options.pop("n", N), folder / "pca_gaussian.npz", **options)


def test_writes_clamped_controls_and_their_poses(quadruped, sampler, tmp_path):
    result = run(quadruped, sampler, tmp_path)
    assert (result.n_chunks, result.chunks_evaluated, result.chunks_resumed) == (N_CHUNKS, 5, 0)

    samples = load_samples(tmp_path / "pca_gaussian.npz")
    used = quadruped.controls.used_indices
    lower, upper = quadruped.controls.lower[used], quadruped.controls.upper[used]
    drawn = sampler.sample(N, np.random.default_rng(11))
    outside = (drawn < lower) | (drawn > upper)
    assert outside.sum() > 0  # the test is only meaningful if something was clamped
    np.testing.assert_array_equal(samples["controls"], np.clip(drawn, lower, upper))
    assert int(samples["n_clamped"]) == result.n_clamped == outside.sum()
    assert int(samples["n_rows_clamped"]) == result.n_rows_clamped == outside.any(axis=1).sum()
    np.testing.assert_array_equal(samples["n_clamped_per_control"], outside.sum(axis=0))

    pose = quadruped.pose(quadruped.expand_used(samples["controls"]))
    assert samples["positions"].shape == (N, quadruped.n_joints, 3)
    np.testing.assert_allclose(samples["positions"], pose.positions, rtol=0, atol=1e-9)
    np.testing.assert_allclose(samples["cog"], pose.cog, rtol=0, atol=1e-9)
    np.testing.assert_allclose(samples["cog_rotation"], pose.cog_rotation, rtol=0, atol=1e-12)
    assert samples["control_names"].tolist() == quadruped.used_controls
    assert samples["joint_names"].tolist() == quadruped.joint_names
    meta = samples["meta"]
    assert meta["rig"] == "quadruped" and meta["sampler"] == "pca_gaussian"
    assert meta["seed"] == 11 and meta["n_samples"] == N
    assert meta["sampler_params"] == {"scale": 1.0, "whiten": True, "n_components": None}

    # nothing left behind but the result
    assert [p.name for p in tmp_path.iterdir()] == ["pca_gaussian.npz"]


def test_a_killed_run_resumes_from_its_finished_chunks_and_gives_the_same_file(
    quadruped, sampler, tmp_path
):
    uninterrupted = WatchedRig(quadruped)
    run(uninterrupted, sampler, tmp_path / "whole")
    assert uninterrupted.calls == N_CHUNKS

    killed = WatchedRig(quadruped, fail_after=2)
    with pytest.raises(Killed):
        run(killed, sampler, tmp_path / "resumed")
    chunks = sorted((tmp_path / "resumed" / "pca_gaussian.chunks").glob("chunk_*.npz"))
    assert [c.name for c in chunks] == ["chunk_000000.npz", "chunk_000001.npz"]
    assert not (tmp_path / "resumed" / "pca_gaussian.npz").exists()

    restarted = WatchedRig(quadruped)
    result = run(restarted, sampler, tmp_path / "resumed")
    assert restarted.calls == N_CHUNKS - 2  # only the unfinished chunks were posed
    assert (result.chunks_resumed, result.chunks_evaluated) == (2, 3)
    whole = (tmp_path / "whole" / "pca_gaussian.npz").read_bytes()
    assert (tmp_path / "resumed" / "pca_gaussian.npz").read_bytes() == whole
    assert not (tmp_path / "resumed" / "pca_gaussian.chunks").exists()


# every run of this test is its own process: the draw (a PCA of a corpus made by a matrix
# product) must match to the last bit between the killed run and its restart, and a test
# process that ran hundreds of tests before may round a BLAS product differently
KILLED_RUN = """
import json, sys
sys.path.insert(0, {tests!r})
from rigmap.rigs import load
from rigmap.sampling import PCAGaussianSampler, supersample
from test_supersample import SlowRig, WatchedRig, quadruped_corpus
rig = load("quadruped")
sampler = PCAGaussianSampler().fit(quadruped_corpus(rig))
watched = {rig_class}(rig)
result = supersample(watched, sampler, {n}, {path!r}, seed=11, chunk_size={chunk}, progress=False)
print(json.dumps({{"calls": watched.calls, "resumed": result.chunks_resumed}}))
"""


def _run_alone(tests: Path, target: Path, chunk: int, rig_class: str = "WatchedRig") -> dict:
    """A supersample run in a fresh process: its rig calls and resumed chunks."""
    script = KILLED_RUN.format(tests=str(tests), n=N, path=str(target), chunk=chunk,
                               rig_class=rig_class)  # fmt: skip
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=300, check=True)  # fmt: skip
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_process_killed_with_sigkill_resumes_to_the_same_file(quadruped, sampler, tmp_path):
    chunk_size = 50
    n_chunks = -(-N // chunk_size)  # 9
    target = tmp_path / "killed" / "pca_gaussian.npz"
    chunk_folder = target.parent / "pca_gaussian.chunks"
    tests = Path(__file__).parent
    script = KILLED_RUN.format(tests=str(tests), n=N, path=str(target), chunk=chunk_size,
                               rig_class="SlowRig")  # fmt: skip
    process = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while len(list(chunk_folder.glob("chunk_*.npz"))) < 2:
            assert process.poll() is None, process.stderr.read().decode()
            assert time.monotonic() < deadline, "the run never finished two chunks"
            time.sleep(0.05)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    assert process.returncode == -signal.SIGKILL
    finished = len(list(chunk_folder.glob("chunk_*.npz")))
    assert 2 <= finished < n_chunks and not target.exists()

    restarted = _run_alone(tests, target, chunk_size)
    assert restarted == {"calls": n_chunks - finished, "resumed": finished}
    whole = _run_alone(tests, tmp_path / "whole" / "pca_gaussian.npz", CHUNK)
    assert whole["resumed"] == 0
    assert target.read_bytes() == (tmp_path / "whole" / "pca_gaussian.npz").read_bytes()
    assert [p.name for p in target.parent.iterdir()] == ["pca_gaussian.npz"]


def test_chunks_from_another_draw_or_a_damaged_file_are_posed_again(quadruped, sampler, tmp_path):
    with pytest.raises(Killed):
        run(WatchedRig(quadruped, fail_after=3), sampler, tmp_path / "a", seed=1)
    other_seed = WatchedRig(quadruped)
    result = run(other_seed, sampler, tmp_path / "a", seed=2)
    assert other_seed.calls == N_CHUNKS and result.chunks_resumed == 0
    run(quadruped, sampler, tmp_path / "b", seed=2)
    assert (tmp_path / "a" / "pca_gaussian.npz").read_bytes() == (
        tmp_path / "b" / "pca_gaussian.npz"
    ).read_bytes()

    with pytest.raises(Killed):
        run(WatchedRig(quadruped, fail_after=3), sampler, tmp_path / "c", seed=2)
    damaged = tmp_path / "c" / "pca_gaussian.chunks" / "chunk_000001.npz"
    damaged.write_bytes(damaged.read_bytes()[:1000])
    restarted = WatchedRig(quadruped)
    result = run(restarted, sampler, tmp_path / "c", seed=2)
    assert restarted.calls == N_CHUNKS - 2 and result.chunks_resumed == 2
    assert (tmp_path / "c" / "pca_gaussian.npz").read_bytes() == (
        tmp_path / "b" / "pca_gaussian.npz"
    ).read_bytes()


def test_the_file_depends_on_the_draw_not_on_chunking_or_time(quadruped, sampler, tmp_path):
    run(quadruped, sampler, tmp_path / "small", chunk_size=60)
    run(quadruped, sampler, tmp_path / "large", chunk_size=10_000)
    small = (tmp_path / "small" / "pca_gaussian.npz").read_bytes()
    assert small == (tmp_path / "large" / "pca_gaussian.npz").read_bytes()
    run(quadruped, sampler, tmp_path / "other_seed", seed=12)
    assert small != (tmp_path / "other_seed" / "pca_gaussian.npz").read_bytes()


def test_given_limits_are_clamped_to_and_counted(quadruped, corpus, tmp_path):
    univariate = UnivariateGaussianSampler().fit(corpus)
    centre = corpus.mean(axis=0)
    lower, upper = centre - 0.01, centre + 0.01
    result = supersample(
        quadruped,
        univariate,
        200,
        tmp_path / "u.npz",
        seed=5,
        lower=lower,
        upper=upper,
        progress=False,
    )
    samples = load_samples(tmp_path / "u.npz")
    drawn = univariate.sample(200, np.random.default_rng(5))
    expected = ((drawn < lower) | (drawn > upper)).sum()
    assert result.n_clamped == expected == int(samples["n_clamped"])
    assert (samples["controls"] >= lower).all() and (samples["controls"] <= upper).all()
    np.testing.assert_array_equal(samples["lower"], lower)
    assert samples["meta"]["limits"] == "given"


def test_no_extra_samples_gives_an_empty_but_complete_file(quadruped, corpus, tmp_path):
    watched = WatchedRig(quadruped)
    result = supersample(
        watched,
        NoExtraSamples().fit(corpus),
        1000,
        tmp_path / "none.npz",
        seed=0,
        progress=False,
    )
    samples = load_samples(tmp_path / "none.npz")
    assert watched.calls == 0 and result.n_samples == 0
    assert samples["controls"].shape == (0, len(quadruped.used_controls))
    assert samples["positions"].shape == (0, quadruped.n_joints, 3)
    assert samples["meta"]["n_requested"] == 1000


def test_a_rig_returning_nan_names_the_chunk_and_keeps_earlier_chunks(quadruped, sampler, tmp_path):
    with pytest.raises(SupersampleError, match=r"chunk 0 \(samples 0\.\.99\).*NaN.*sample 7"):
        run(WatchedRig(quadruped, corrupt=True), sampler, tmp_path)
    assert not list((tmp_path / "pca_gaussian.chunks").glob("*.npz"))
    assert not (tmp_path / "pca_gaussian.npz").exists()


def test_bad_arguments_get_clear_errors(quadruped, corpus, sampler, tmp_path):
    with pytest.raises(SamplerNotFittedError, match="not fitted"):
        run(quadruped, PCAGaussianSampler(), tmp_path)
    narrow = PCAGaussianSampler().fit(corpus[:, :5])
    with pytest.raises(SupersampleError, match="fitted on 5 controls but rig 'quadruped' has"):
        run(quadruped, narrow, tmp_path)
    with pytest.raises(SamplerInputError, match="must be >= 0, got -3"):
        run(quadruped, sampler, tmp_path, n=-3)
    with pytest.raises(SamplerInputError, match="chunk_size must be an integer >= 1, got 0"):
        run(quadruped, sampler, tmp_path, chunk_size=0)
    with pytest.raises(SamplerInputError, match="seed must be an integer >= 0"):
        run(quadruped, sampler, tmp_path, seed=-1)
    with pytest.raises(SupersampleError, match=r"must be a \.npz file"):
        supersample(quadruped, sampler, 10, tmp_path / "samples.txt", seed=0)
    assert not any(tmp_path.iterdir())


def test_meta_is_plain_json(quadruped, sampler, tmp_path):
    run(quadruped, sampler, tmp_path, n=20)
    with np.load(tmp_path / "pca_gaussian.npz", allow_pickle=False) as data:
        meta = json.loads(str(data["meta"]))
        assert meta["n_clamped"] == int(data["n_clamped"])


BUILT_IN_RIGS = ("quadruped", "biped", "face", "squirrel")


@pytest.fixture(scope="module", params=BUILT_IN_RIGS)
def built_in_rig(request):
    from rigmap.rigs import load

    try:
        return load(request.param)
    except ImportError:
        pytest.skip(f"rig {request.param!r} is not written yet")


@pytest.mark.parametrize("name", available())
def test_every_strategy_runs_on_every_built_in_rig(built_in_rig, name, tmp_path):
    corpus = quadruped_corpus(built_in_rig)[:120]
    # a small diagonal mixture keeps this fast; the full 25-component one is in test_sampling
    options = {"n_components": 4, "covariance_type": "diag"} if name == "gmm" else {}
    sampler = make_sampler(name, **options).fit(corpus)
    result = supersample(
        built_in_rig, sampler, 20, tmp_path / f"{name}.npz", seed=0, chunk_size=10, progress=False
    )
    samples = load_samples(tmp_path / f"{name}.npz")
    n = 0 if name == "none" else 20
    assert result.n_samples == n and result.n_chunks == -(-n // 10)
    assert samples["controls"].shape == (n, len(built_in_rig.used_controls))
    assert samples["positions"].shape == (n, len(built_in_rig.joint_names), 3)
    assert np.isfinite(samples["positions"]).all()
    used = built_in_rig.controls.used_indices
    assert (samples["controls"] >= built_in_rig.controls.lower[used]).all()
    assert (samples["controls"] <= built_in_rig.controls.upper[used]).all()
