"""Bad inputs given to the real DVC stages (``pipelines/*.py`` in a child process).

Each run must exit non-zero with a message that names the file or the field, and leave
no model folder behind. Issue 20, defects 6 (a damaged samples ``.npz`` gave a raw
``BadZipFile`` without the file's name) and 9 (a learning rate of 1e9 trained to an
infinite loss and saved the model with exit 0).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rigmap.sampling.reproducible_npz import save_npz_atomically

REPO = Path(__file__).resolve().parents[1]


def _stage(script: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO / "pipelines")])
    return subprocess.run(
        [sys.executable, str(REPO / "pipelines" / script), *args], cwd=cwd, env=env,
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """The quadruped's corpus and poses, made by the real animate and pose stages."""
    folder = tmp_path_factory.mktemp("stages")
    for script in ("animate.py", "pose.py"):
        done = _stage(script, "rig=quadruped", f"paths.data={folder / 'data'}", cwd=folder)
        assert done.returncode == 0, done.stderr[-3000:]
    return folder


def _fit(data: Path, models: Path, *overrides: str) -> subprocess.CompletedProcess:
    return _stage(
        "fit.py", "rig=quadruped", "regressor=nn", f"paths.data={data / 'data'}",
        f"paths.models={models}", *overrides, cwd=data,
    )  # fmt: skip


def _samples(data: Path, damage) -> Path:
    path = data / "data" / "quadruped" / "samples" / "pca_gaussian.npz"
    rng = np.random.default_rng(0)
    save_npz_atomically(path, {"controls": rng.normal(size=(200, 218)), "meta": np.array("{}")})
    path.write_bytes(damage(path.read_bytes()))
    return path


def _truncate(data: bytes) -> bytes:
    return data[: len(data) // 2]


def _flip(data: bytes) -> bytes:
    flipped = bytearray(data)
    flipped[len(flipped) // 2] ^= 0x04
    return bytes(flipped)


@pytest.mark.slow
@pytest.mark.parametrize("damage", [_truncate, _flip], ids=["truncated", "bit-flipped"])
def test_fit_on_a_damaged_samples_file_names_it(data, tmp_path, damage):
    """Defect 6, at the stage: the error names the samples file and says what to do."""
    path = _samples(data, damage)
    done = _fit(data, tmp_path / "models", "sampler=pca_gaussian")
    assert done.returncode == 2 and "Traceback" not in done.stderr  # one clear message
    assert f"samples file {path} is damaged" in done.stderr and "dvc repro" in done.stderr
    assert "BadZipFile:" not in done.stderr.replace("(BadZipFile:", "")  # only as the cause
    assert not (tmp_path / "models").exists()


@pytest.mark.slow
def test_a_diverging_fit_saves_no_model(data, tmp_path):
    """Defect 9, at the stage: learning_rate=1e9 used to save a model with an infinite loss."""
    done = _fit(data, tmp_path / "models", "sampler=none", "regressor.learning_rate=1e9")
    assert done.returncode == 2 and "Traceback" not in done.stderr  # one clear message
    assert "training diverged" in done.stderr and "regressor.learning_rate" in done.stderr
    assert not (tmp_path / "models").exists()
