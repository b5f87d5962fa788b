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


class _StallingServer:
    """An MLflow server that answers ``GET /health`` and then never answers an API call
    (until the test ends): what a wedged server behind a healthy proxy looks like."""

    def __init__(self):
        import http.server
        import threading

        self.api_requests = 0
        self.release = threading.Event()
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def _stall(self):
                if self.path.startswith("/health"):
                    self.send_response(200)
                    self.end_headers()
                    self.wfile.write(b"OK")
                    return
                outer.api_requests += 1
                outer.release.wait(60)

            do_GET = do_POST = _stall

            def log_message(self, *args):
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.uri = f"http://127.0.0.1:{self.server.server_address[1]}"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.release.set()
        self.server.shutdown()
        self.server.server_close()


def test_a_server_that_stalls_after_health_is_named_in_one_line_after_bounded_retries(
    tmp_path, monkeypatch
):
    """The issue's trial: /health answers, then every call hangs. Each request waits
    tracking.request_timeout_s and is retried tracking.request_retries times, then the
    stage and the CLI say so in one line (it used to wait 253 s and end in five chained
    MlflowException tracebacks)."""
    from mlflow.exceptions import MlflowException

    from rigmap.app.stage import _exit_if_users
    from rigmap.cli import expected_failure, failure_message
    from rigmap.tracking import Tracker
    from rigmap.tracking.store import TrackingUnavailableError, tracking_failure

    for name in ("MLFLOW_HTTP_REQUEST_TIMEOUT", "MLFLOW_HTTP_REQUEST_MAX_RETRIES"):
        monkeypatch.delenv(name, raising=False)
    server = _StallingServer()
    try:
        config = {"uri": server.uri, "request_timeout_s": 1, "request_retries": 1}
        tracker = Tracker.from_config(config, root=tmp_path)
        with pytest.raises(MlflowException) as raised:
            tracker.experiment_id("quadruped")
    finally:
        server.close()
    assert server.api_requests == 2  # one try and one retry, no more
    failure = tracking_failure(raised.value)
    assert isinstance(failure, TrackingUnavailableError)
    message = failure_message(failure)
    assert "\n" not in str(failure) and expected_failure(failure)
    assert f"did not answer {server.uri}/api/2.0/mlflow/experiments/" in message
    assert "after 1 retry of 1 s; tracking.request_timeout_s" in message
    # the stages' boundary prints it as one line and exits 2
    with pytest.raises(SystemExit) as exited:
        _exit_if_users("fit", raised.value)
    assert exited.value.code == 2
    # anything else is left alone
    assert tracking_failure(ValueError("API request to x")) is None


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("request_timeout_s", 0, "tracking.request_timeout_s must be whole seconds >= 1, got 0"),
        ("request_timeout_s", 2.5, "tracking.request_timeout_s must be whole seconds >= 1"),
        ("request_retries", -1, "tracking.request_retries must be an integer >= 0, got -1"),
    ],
)
def test_bad_request_bounds_are_named(tmp_path, field, value, message):
    from rigmap.tracking import Tracker

    server = _StallingServer()
    try:
        with pytest.raises(ValueError, match=message):
            Tracker.from_config({"uri": server.uri, field: value}, root=tmp_path)
    finally:
        server.close()
