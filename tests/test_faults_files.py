"""Damaged files on disk and training that goes wrong (issue 20, defects 6 and 9).

- a truncated or bit-flipped samples ``.npz`` gave a raw ``BadZipFile`` without the
  file's name (defect 6);
- a corrupted cached Rigify ``.blend`` failed every load until deleted by hand (defect 6);
- a learning rate of 1e9 trained to an infinite loss and the model was saved (defect 9);
- network training is bit-identical in two processes (issue 20, "reproducible numbers").
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rigmap.regression.network import FeedForwardRegressor, TrainingDivergedError
from rigmap.sampling.reproducible_npz import NpzFileError, read_npz, save_npz_atomically
from rigmap.sampling.supersample import load_samples

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def samples_file(tmp_path) -> Path:
    rng = np.random.default_rng(0)
    return save_npz_atomically(
        tmp_path / "samples" / "pca_gaussian.npz",
        {
            "controls": rng.normal(size=(50, 4)),
            "positions": rng.normal(size=(50, 3, 3)),
            "meta": np.array('{"rig": "quadruped"}'),
        },
    )


def test_intact_samples_file_reads(samples_file):
    assert load_samples(samples_file)["meta"] == {"rig": "quadruped"}


def test_truncated_samples_file_names_the_file(samples_file):
    """Defect 6: a truncated .npz gave a raw BadZipFile traceback without the file's name."""
    data = samples_file.read_bytes()
    samples_file.write_bytes(data[: len(data) // 2])
    with pytest.raises(NpzFileError, match=rf"samples file {samples_file} is damaged"):
        load_samples(samples_file)


def test_bit_flipped_samples_file_names_the_file(samples_file):
    """Defect 6: one flipped bit inside an array is caught by the member's CRC-32."""
    data = bytearray(samples_file.read_bytes())
    data[len(data) // 2] ^= 0x10
    samples_file.write_bytes(bytes(data))
    with pytest.raises(NpzFileError, match=r"is damaged .*CRC") as error:
        load_samples(samples_file)
    assert str(samples_file) in str(error.value)


def test_samples_file_without_an_array_or_meta(tmp_path):
    partial = save_npz_atomically(tmp_path / "a.npz", {"controls": np.zeros((2, 2))})
    with pytest.raises(NpzFileError, match=r"a\.npz: lacks the arrays \['positions', 'meta'\]"):
        load_samples(partial)
    with pytest.raises(NpzFileError, match="no such file"):
        read_npz(tmp_path / "missing.npz")
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(NpzFileError, match=r"text\.npz is damaged or not a \.npz file"):
        read_npz(tmp_path / "text.npz")


def test_a_diverging_network_fails_without_a_model(tmp_path):
    """Defect 9: learning rate 1e9 trained to an infinite loss and saved the model (exit 0)."""
    rng = np.random.default_rng(1)
    X, Y = rng.normal(size=(64, 6)), rng.normal(size=(64, 3))
    network = FeedForwardRegressor(hidden=16, epochs=3, learning_rate=1e9, progress=False)
    with pytest.raises(TrainingDivergedError, match=r"diverged.*learning_rate=1000000000"):
        network.fit(X, Y)
    assert not hasattr(network, "loss_history_")  # nothing fitted that could be saved


TRAIN_IN_A_PROCESS = """
import sys, numpy as np
from rigmap.regression.network import FeedForwardRegressor
rng = np.random.default_rng(7)
X = rng.normal(size=(300, 12)); Y = np.tanh(X[:, :5] @ rng.normal(size=(5, 4)))
FeedForwardRegressor(hidden=64, epochs=3, batch_size=8, seed=3, progress=False).fit(X, Y).save(
    sys.argv[1])
"""


def test_network_training_is_bit_identical_in_two_processes(tmp_path):
    """Issue 20: the same config gives the same weights, file for file, in separate processes."""
    for run in ("first", "second"):
        done = subprocess.run(
            [sys.executable, "-c", TRAIN_IN_A_PROCESS, str(tmp_path / run)],
            capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-2000:]
    first = sorted(p.name for p in (tmp_path / "first").iterdir())
    assert first == ["nn.json", "nn.npz"]
    for name in first:
        assert (tmp_path / "first" / name).read_bytes() == (tmp_path / "second" / name).read_bytes()


@pytest.mark.blender
@pytest.mark.slow
def test_a_corrupted_cached_rigify_blend_is_generated_again(tmp_path, monkeypatch):
    """Defect 6: a truncated or bit-flipped cached .blend failed every load."""
    from rigmap.rigs.blender.cache import cached_file_ok
    from rigmap.rigs.blender.rigify import generation_info, rigify_blend

    monkeypatch.setenv("RIGMAP_CACHE", str(tmp_path / "cache"))
    path = rigify_blend("wolf")
    good = path.read_bytes()
    assert cached_file_ok(path) and len(generation_info(path)["sha256"]) == 64

    path.write_bytes(good[: len(good) // 3])  # truncated (a killed copy, a full disk)
    assert not cached_file_ok(path)
    assert rigify_blend("wolf") == path and cached_file_ok(path)

    flipped = bytearray(path.read_bytes())
    flipped[len(flipped) // 2] ^= 0x01
    path.write_bytes(bytes(flipped))
    assert rigify_blend("wolf") == path and cached_file_ok(path)
    assert len(path.read_bytes()) > len(good) // 2
