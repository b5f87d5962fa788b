"""A stage stopped mid-way never leaves its MLflow run RUNNING (issue 20, defect 4).

The parent run is opened by the real ``rigmap.tracking`` helpers on a local SQLite
store in a child process, which is then sent SIGTERM (what ``dvc`` and CI send on
cancel) or hits an ordinary error.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

STAGE = """
import sys, time
from rigmap.tracking import Tracker, start_parent_run
tracker = Tracker.open(sys.argv[1], root=sys.argv[2])
with start_parent_run(tracker, "quadruped", name="stage") as parent:
    print(parent.run_id, flush=True)
    if sys.argv[3] == "error":
        raise ValueError("a normal error half-way through the stage")
    time.sleep(120)
"""


def _stage(tmp_path: Path, how: str) -> tuple[subprocess.Popen, str, str]:
    uri = f"sqlite:///{tmp_path / 'mlruns.db'}"
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), env.get("PYTHONPATH", "")])
    process = subprocess.Popen(
        [sys.executable, "-c", STAGE, uri, str(tmp_path), how],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip
    run_id = process.stdout.readline().strip()
    assert run_id, process.stderr.read()
    return process, uri, run_id


def _status(uri: str, run_id: str) -> str:
    from mlflow import MlflowClient

    return MlflowClient(uri).get_run(run_id).info.status


@pytest.mark.slow
def test_sigterm_ends_the_parent_run_killed(tmp_path):
    """Defect 4: an evaluate stage killed mid-way left its parent run RUNNING forever."""
    process, uri, run_id = _stage(tmp_path, "sleep")
    try:
        time.sleep(0.5)
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=60)
    finally:
        process.kill()
        process.wait()
    assert process.returncode == 128 + signal.SIGTERM
    assert _status(uri, run_id) == "KILLED"


@pytest.mark.slow
def test_a_normal_error_ends_the_parent_run_failed(tmp_path):
    process, uri, run_id = _stage(tmp_path, "error")
    process.wait(timeout=60)
    assert process.returncode == 1 and "a normal error" in process.stderr.read()
    assert _status(uri, run_id) == "FAILED"
