"""``mlflow models serve`` of a saved model folder, as a context manager that always stops it.

Used by the tests and benchmarks of the map model (:mod:`rigmap.tracking.map_model`) and by
anyone who wants the REST answer on this machine: the server runs in the current Python
environment (``--env-manager local``, so no virtualenv is built) on 127.0.0.1, in its own
process group, and the whole group (uvicorn and its worker) is stopped on exit.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rigmap.errors import RigmapError

START_TIMEOUT_S = 180.0  # ours: a loaded 2-core machine needs 10-60 s to import mlflow and start
REQUEST_TIMEOUT_S = 300  # ours: MLflow's default of 60 s is short for refinement on a busy host


class ModelServerError(RigmapError, RuntimeError):
    """The model server did not start; the message carries the end of its log."""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@contextmanager
def served_model(
    folder: str | os.PathLike,
    *,
    port: int | None = None,
    start_timeout_s: float = START_TIMEOUT_S,
    request_timeout_s: int = REQUEST_TIMEOUT_S,
) -> Iterator[str]:
    """``http://127.0.0.1:<port>`` of ``mlflow models serve -m folder`` once ``/ping`` answers.

    The folder's ``MLmodel`` must name one of rigmap's loaders (no code from the folder)."""
    from rigmap.tracking.pyfunc_model import check_mlmodel

    check_mlmodel(Path(folder))
    port = port or free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    # the server execs `uvicorn` by name: this interpreter's own, even from an unactivated venv
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    command = [
        sys.executable,
        "-m",
        "mlflow",
        "models",
        "serve",
        "-m",
        str(folder),
        "--env-manager",
        "local",
        "-h",
        "127.0.0.1",
        "-p",
        str(port),
        "-w",
        "1",
        "-t",
        str(int(request_timeout_s)),
    ]
    url = f"http://127.0.0.1:{port}"
    with tempfile.TemporaryDirectory(prefix="rigmap-serve-") as scratch:
        log_path = Path(scratch) / "serve.log"
        with open(log_path, "w") as log:
            server = subprocess.Popen(
                command,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=env,
                cwd=scratch,
                start_new_session=True,
            )
            try:
                _wait_for_ping(server, url, log_path, start_timeout_s)
                yield url
            finally:
                _stop(server)


def post_json(url: str, body: dict, timeout_s: float = REQUEST_TIMEOUT_S) -> tuple[int, dict]:
    """POST ``body`` as JSON; the HTTP status and the decoded answer (errors included)."""
    request = urllib.request.Request(
        url,
        data=json.dumps(body).encode(),
        method="POST",
        headers={"Content-Type": "application/json"},
    )
    try:
        with urllib.request.urlopen(request, timeout=timeout_s) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read())


def _wait_for_ping(server: subprocess.Popen, url: str, log: Path, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        if server.poll() is not None:
            raise ModelServerError(
                f"mlflow models serve exited with {server.returncode}: {log.read_text()[-3000:]}"
            )
        try:
            with urllib.request.urlopen(f"{url}/ping", timeout=5) as response:
                if response.status == 200:
                    return
        except OSError:
            pass
        if time.monotonic() > deadline:
            raise ModelServerError(
                f"mlflow models serve not up in {timeout_s:.0f} s: {log.read_text()[-3000:]}"
            )
        time.sleep(0.5)


def _stop(server: subprocess.Popen) -> None:
    """SIGTERM the server's process group, then SIGKILL what lingers; reap the leader."""
    for sig, wait_s in ((signal.SIGTERM, 15.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(server.pid, sig)
        except ProcessLookupError:
            break
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            server.poll()
            try:
                os.killpg(server.pid, 0)
            except ProcessLookupError:
                server.wait()
                return
            time.sleep(0.1)
    server.poll()
