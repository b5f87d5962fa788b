"""Shared fixtures: built-in rigs are cached by the registry, so loading is cheap."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"


def pytest_runtest_setup(item):
    """A ``blender`` or ``browser`` test fails, never skips, without the worker environment
    or Chromium: `make test` installs both, so a missing one is a broken set-up, not a
    reason to test less."""
    if item.get_closest_marker("browser") is not None:
        from browser import chromium_path

        if chromium_path() is None:
            pytest.fail(
                "Chromium is missing: make browser (apt-get install chromium)", pytrace=False
            )
    if item.get_closest_marker("blender") is None:
        return
    from rigmap.rigs.blender import blender_available
    from rigmap.rigs.blender.environment import INSTALL_HINT

    if not blender_available():
        pytest.fail(f"the Blender worker environment is missing: {INSTALL_HINT}", pytrace=False)


@pytest.fixture(autouse=True)
def no_mlflow_state_from_earlier_tests(monkeypatch):
    """Each test starts without MLflow's process-wide state: an active run, an active
    experiment, or the MLFLOW_EXPERIMENT_ID / MLFLOW_RUN_ID that ``mlflow.set_experiment``
    and runs leave for child processes. Without this a test that resumes a run on a real
    server failed after earlier tests ("active experiment ID does not match")."""
    import mlflow
    import mlflow.tracking.fluent as fluent

    while mlflow.active_run() is not None:
        mlflow.end_run()
    for name in ("MLFLOW_EXPERIMENT_ID", "MLFLOW_RUN_ID"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(fluent, "_active_experiment_id", None)


@pytest.fixture(scope="session")
def quadruped():
    from rigmap.rigs import load

    return load("quadruped")


@pytest.fixture(scope="session")
def biped():
    from rigmap.rigs import load

    return load("biped")


# --------------------------------------------------------------------------- a real mlflow server
MLFLOW_SERVER_START_TIMEOUT_S = 120  # a loaded 2-core machine needs 20-45 s to start it


@pytest.fixture(scope="session")
def mlflow_server(tmp_path_factory):
    """``http://127.0.0.1:<port>`` of a fresh `mlflow server` (temporary SQLite backend and
    artifact folder, free port, own process group); the whole group is killed at the end."""
    import os
    import signal
    import socket
    import subprocess
    import sys
    import time
    import urllib.request

    folder = tmp_path_factory.mktemp("mlflow-server")
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env["MLFLOW_SERVER_ENABLE_JOB_EXECUTION"] = "false"  # no huey job-runner processes
    log_path = folder / "server.log"
    log = open(log_path, "w")
    server = subprocess.Popen(
        [sys.executable, "-m", "mlflow", "server", "--host", "127.0.0.1", "--port", str(port),
         "--workers", "1", "--backend-store-uri", f"sqlite:///{folder / 'backend.db'}",
         "--artifacts-destination", str(folder / "artifacts")],
        stdout=log, stderr=subprocess.STDOUT, env=env, start_new_session=True,
    )  # fmt: skip
    uri = f"http://127.0.0.1:{port}"

    def tail() -> str:
        log.flush()
        return log_path.read_text()[-2000:]

    try:
        deadline = time.monotonic() + MLFLOW_SERVER_START_TIMEOUT_S
        while True:
            if server.poll() is not None:
                raise RuntimeError(f"mlflow server exited with {server.returncode}: {tail()}")
            try:
                with urllib.request.urlopen(f"{uri}/health", timeout=2) as response:
                    if response.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f"mlflow server not up in {MLFLOW_SERVER_START_TIMEOUT_S} s: {tail()}"
                )
            time.sleep(0.25)
        yield uri
    finally:
        # SIGTERM the server's process group (uvicorn children), then SIGKILL what lingers
        for sig, wait_s in ((signal.SIGTERM, 15.0), (signal.SIGKILL, 5.0)):
            try:
                os.killpg(server.pid, sig)
            except ProcessLookupError:
                break
            deadline = time.monotonic() + wait_s
            while time.monotonic() < deadline:
                server.poll()  # reap the leader so the group can empty
                try:
                    os.killpg(server.pid, 0)
                except ProcessLookupError:
                    break
                time.sleep(0.1)
            else:
                continue
            break
        log.close()


# ------------------------------------------------------- mlflow server on PostgreSQL (the script)
@pytest.fixture(scope="session")
def pg_tracking_server():
    """``http://127.0.0.1:<port>`` of `scripts/tracking_server.sh start`: a fresh PostgreSQL
    cluster and mlflow server on free ports, in a folder the `postgres` user can enter
    (pytest's own temporary folders are private to root); stopped and removed at the end."""
    import os
    import shutil
    import socket
    import subprocess
    import tempfile

    def free_port() -> int:
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            return sock.getsockname()[1]

    folder = tempfile.mkdtemp(prefix="rigmap-pg-")
    os.chmod(folder, 0o755)
    script = Path(__file__).resolve().parents[1] / "scripts" / "tracking_server.sh"
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env.update(RIGMAP_TRACKING_DIR=folder, RIGMAP_PG_PORT=str(free_port()),
               RIGMAP_MLFLOW_PORT=str(free_port()),
               RIGMAP_TRACKING_STOP_GRACE_S="2")  # fmt: skip
    started = subprocess.run(
        ["bash", str(script), "start"], env=env, capture_output=True, text=True, timeout=300
    )
    try:
        if started.returncode != 0:
            raise RuntimeError(f"tracking_server.sh start failed: {started.stderr[-3000:]}")
        uri = started.stdout.strip().splitlines()[-1].split("=", 1)[1]
        backend = started.stdout.split("backend: ", 1)[1].split()[0]
        yield SimpleNamespace(uri=uri, backend=backend, folder=Path(folder), env=env)
    finally:
        subprocess.run(["bash", str(script), "stop"], env=env, capture_output=True, timeout=120)
        shutil.rmtree(folder, ignore_errors=True)
