"""``kill -9`` at points of the pipeline, then the stage re-run (what ``dvc repro`` does).

For each point a real stage runs on the quadruped in a child process and is killed
with SIGKILL once its output says it is mid-way (animate: after the first clip file;
pose: while posing the first split; fit: during network training). Right after the
kill no output may be half-written (each is absent or whole, no stray temporaries);
after the re-run every output is byte-identical to an uninterrupted run's. The
supersample kill point lives in ``test_supersample.py`` and the Blender worker kill in
``test_blender_pool.py``; they are not repeated here.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
STAGES = {
    # stage: (its arguments, output files under the run folder, the line that means "mid-way")
    "animate": (
        ["pipelines/animate.py", "rig=quadruped"],
        ["data/quadruped/corpus/train.parquet", "data/quadruped/corpus/test.parquet"],
        "quadruped train:",
    ),
    "pose": (
        ["pipelines/pose.py", "rig=quadruped"],
        ["data/quadruped/poses/train.parquet", "data/quadruped/poses/test.parquet"],
        "posing quadruped train",
    ),
    "fit": (
        ["pipelines/fit.py", "rig=quadruped", "regressor=nn", "sampler=none"],
        [
            "models/quadruped/nn-none-none/nn.npz",
            "models/quadruped/nn-none-none/nn.json",
            "models/quadruped/nn-none-none/placement.json",
        ],
        "network training:",
    ),
}


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO / "pipelines")])
    return env


def _command(stage: str, folder: Path) -> list[str]:
    args = STAGES[stage][0]
    paths = [f"paths.data={folder / 'data'}", f"paths.models={folder / 'models'}"]
    return [sys.executable, str(REPO / args[0]), *args[1:], *paths]


def _run(stage: str, folder: Path) -> None:
    done = subprocess.run(
        _command(stage, folder), cwd=folder, env=_env(), capture_output=True, text=True,
        timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]


def _kill_mid_way(stage: str, folder: Path) -> None:
    process = subprocess.Popen(
        _command(stage, folder), cwd=folder, env=_env(),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )  # fmt: skip
    seen = bytearray()
    reader = threading.Thread(target=lambda: _drain(process, seen), daemon=True)
    reader.start()
    marker = STAGES[stage][2].encode()
    try:
        deadline = time.monotonic() + 300
        while marker not in seen:
            assert process.poll() is None, seen.decode(errors="replace")[-3000:]
            assert time.monotonic() < deadline, "the stage never reached the kill point"
            time.sleep(0.01)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    assert process.returncode == -signal.SIGKILL


def _drain(process: subprocess.Popen, seen: bytearray) -> None:
    while chunk := process.stdout.read1(1024):
        seen.extend(chunk)


def _prepare(stage: str, folder: Path, reference: Path) -> None:
    """The stage's inputs: the reference run's outputs of the stages before it."""
    order = list(STAGES)
    for earlier in order[: order.index(stage)]:
        for output in STAGES[earlier][1]:
            target = folder / output
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes((reference / output).read_bytes())


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """Inputs for every stage: one uninterrupted run of the stages before fit."""
    folder = tmp_path_factory.mktemp("inputs")
    for stage in list(STAGES)[:-1]:
        _run(stage, folder)
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("stage", list(STAGES))
def test_kill_9_mid_stage_then_rerun_gives_identical_outputs(stage, reference, tmp_path):
    """Outputs record their input paths, so the uninterrupted run is made in the same folder."""
    _prepare(stage, tmp_path, reference)
    outputs = STAGES[stage][1]
    _run(stage, tmp_path)
    whole = {output: (tmp_path / output).read_bytes() for output in outputs}
    for output in outputs:
        (tmp_path / output).unlink()

    _kill_mid_way(stage, tmp_path)
    for output in outputs:  # nothing half-written: each output absent or complete
        path = tmp_path / output
        assert not path.exists() or path.read_bytes() == whole[output]
    touched = {(tmp_path / output).parent for output in outputs}

    _run(stage, tmp_path)  # dvc repro re-runs the stage
    for output in outputs:
        assert (tmp_path / output).read_bytes() == whole[output], output
    for folder in touched:  # no temporary file or staging folder is left behind
        assert not [p.name for p in folder.iterdir() if p.name.startswith(".")], folder
