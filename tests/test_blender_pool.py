"""The worker pool's failure handling, against a small stand-in worker (no Blender needed).

The stand-in speaks the real protocol (it imports the same ``protocol`` module
the Blender worker does) and computes a known function of each row, so crash,
timeout and restart behaviour is checked on real processes in milliseconds.
"""

from __future__ import annotations

import gc
import os
import signal
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from rigmap.rigs.blender import environment
from rigmap.rigs.blender.pool import WorkerPool
from rigmap.rigs.blender.worker_process import (
    RequestTimeout,
    WorkerCrashed,
    WorkerError,
    WorkerProcess,
)

PROTOCOL_DIR = Path(environment.WORKER_SCRIPT).parent

STAND_IN = textwrap.dedent(
    """
    import os, sys, time
    sys.path.insert(0, sys.argv[1])
    import numpy as np
    import protocol

    flags = sys.argv[2:]
    if "--die-at-start" in flags:
        sys.stderr.write("stand-in: cannot start\\n")
        sys.exit(3)
    out = sys.stdout.buffer
    if "--junk" in flags:  # what a Blender executable prints before the script runs
        out.write(b"Blender 5.0.1\\nRead blend: startup.blend\\n")
        out.flush()
    read = sys.stdin.buffer.read
    out.write(protocol.encode_frame({"op": "hello", "protocol": protocol.PROTOCOL_VERSION}))
    out.flush()
    offset = 0.0
    while True:
        frame = protocol.read_frame(read)
        if frame is None:
            sys.exit(0)
        header, arrays = frame
        op, args = header["op"], header.get("args", {})
        reply, payload = {"ok": True}, {}
        if op == "exit":
            out.write(protocol.encode_frame(reply)); out.flush(); sys.exit(0)
        elif op == "load":
            offset = float(args["offset"])
            reply["loaded"] = offset
        elif op == "evaluate":
            y = arrays["controls"]
            if args.get("hang_on") is not None and (y == args["hang_on"]).any():
                time.sleep(60)
            time.sleep(float(args.get("delay", 0.0)))
            payload = {"positions": y * 2.0 + offset, "pid": np.full(len(y), os.getpid())}
        else:
            reply = {"ok": False, "error": f"ValueError: unknown operation {op!r}"}
        out.write(protocol.encode_frame(reply, payload))
        out.flush()
    """
)


@pytest.fixture
def stand_in(tmp_path):
    script = tmp_path / "stand_in.py"
    script.write_text(STAND_IN)

    def argv(*flags):
        return lambda _slot: [sys.executable, str(script), str(PROTOCOL_DIR), *flags]

    return argv


def make_pool(stand_in, tmp_path, **kwargs):
    kwargs.setdefault("workers", 2)
    return WorkerPool(
        stand_in(),
        setup=[("load", {"offset": 0.5})],
        log_dir=tmp_path / "logs",
        **kwargs,
    )


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_batch_is_split_over_workers_and_reassembled_in_order(stand_in, tmp_path):
    Y = np.arange(60.0).reshape(20, 3)
    with make_pool(stand_in, tmp_path) as pool:
        out = pool.map_rows("evaluate", {"controls": Y}, chunk_rows=3)
        assert pool.setup_replies == [{"ok": True, "loaded": 0.5}]
    assert np.array_equal(out["positions"], Y * 2.0 + 0.5)
    assert len(set(out["pid"].tolist())) == 2  # both workers took chunks


def test_killed_worker_mid_batch_is_restarted_and_the_result_is_identical(stand_in, tmp_path):
    Y = np.random.default_rng(0).normal(size=(40, 5))
    seen_pids: set[int] = set()
    killed: list[int] = []
    with make_pool(stand_in, tmp_path) as pool:
        reference = pool.map_rows("evaluate", {"controls": Y}, chunk_rows=4)["positions"]
        seen_pids.update(pool.pids())
        victim = pool.pids()[0]

        def kill_once(_rows):
            if not killed:
                os.kill(victim, signal.SIGKILL)
                killed.append(victim)

        # 20 slow chunks: after the first one finishes the victim still has work to lose,
        # even when a loaded machine schedules the two workers unevenly
        out = pool.map_rows(
            "evaluate", {"controls": Y}, args={"delay": 0.1}, chunk_rows=2, on_chunk_done=kill_once
        )
        seen_pids.update(pool.pids())
        assert pool.restarts >= 1
        assert victim not in pool.pids()
    assert np.array_equal(out["positions"], reference)
    assert killed == [victim]
    assert all(gone(pid) for pid in seen_pids), "a worker outlived the pool"


def test_hung_worker_times_out_is_killed_and_the_pool_recovers(stand_in, tmp_path):
    with make_pool(stand_in, tmp_path, workers=1, timeout=1.0, max_retries=1) as pool:
        pool.start()
        first = pool.pids()[0]
        started = time.monotonic()
        with pytest.raises(RequestTimeout, match="did not answer 'evaluate'"):
            pool.map_rows("evaluate", {"controls": np.array([[7.0]])}, args={"hang_on": 7.0})
        assert time.monotonic() - started < 30  # two attempts of 1 s plus restarts
        assert pool.restarts == 2 and gone(first)
        out = pool.map_rows("evaluate", {"controls": np.array([[1.0]])})
        assert out["positions"].tolist() == [[2.5]]


def test_error_inside_a_request_keeps_the_worker(stand_in, tmp_path):
    with make_pool(stand_in, tmp_path, workers=1) as pool:
        pool.start()
        pid = pool.pids()[0]
        with pytest.raises(WorkerError, match="unknown operation 'frobnicate'"):
            pool.call("frobnicate")
        assert pool.pids() == [pid] and pool.restarts == 0


def test_dropping_the_pool_without_close_kills_its_workers(stand_in, tmp_path):
    pool = make_pool(stand_in, tmp_path)
    pool.start()
    pids = pool.pids()
    assert len(pids) == 2 and not any(gone(p) for p in pids)
    del pool
    gc.collect()
    assert all(gone(p) for p in pids)


def test_output_printed_before_hello_is_skipped(stand_in, tmp_path):
    worker = WorkerProcess(stand_in("--junk")(0), log_dir=tmp_path)
    try:
        header, out = worker.request("evaluate", arrays={"controls": np.ones((1, 2))})
        assert header["ok"] and out["positions"].tolist() == [[2.0, 2.0]]
    finally:
        worker.close()
    assert gone(worker.pid)


def test_worker_that_dies_at_start_is_reported_with_its_log(stand_in, tmp_path):
    with pytest.raises(WorkerCrashed, match="cannot start"):
        WorkerProcess(stand_in("--die-at-start")(0), log_dir=tmp_path)


def test_missing_blender_names_the_install_command(tmp_path, monkeypatch):
    monkeypatch.setenv(environment.ENV_VAR, str(tmp_path / "no-such-blender"))
    with pytest.raises(environment.BlenderNotFoundError, match="make blender"):
        environment.find_blender()
    assert not environment.blender_available()


def test_blender_executable_is_run_in_background_mode(tmp_path, monkeypatch):
    fake = tmp_path / "blender"
    fake.write_text("#!/bin/sh\n")
    fake.chmod(0o755)
    monkeypatch.setenv(environment.ENV_VAR, str(fake))
    command = environment.find_blender()
    argv = command.argv("--pin-cpu", "1")
    assert command.kind == "blender"
    assert argv[:2] == [str(fake), "-b"]
    assert argv[argv.index("--python") + 1] == str(environment.WORKER_SCRIPT)
    assert argv[argv.index("--") + 1 :] == ["--pin-cpu", "1"]
