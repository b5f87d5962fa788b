"""A pool of Blender workers that splits batches of rows between them.

Each worker is brought to the same state by replaying ``setup`` requests (for a
rig: ``load``) when it starts and again whenever it is restarted. A batch is cut
into chunks; one thread per worker takes chunks from a shared queue. A chunk
whose worker crashes or times out is put back and evaluated again on a fresh
worker, so the caller gets the same numbers as without the failure (the rig is
a pure function of its controls). Workers never outlive the pool: ``close``,
the context manager, garbage collection and interpreter exit all kill them.
"""

from __future__ import annotations

import math
import os
import threading
import time
import weakref
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from rigmap.rigs.blender.worker_process import WorkerCrashed, WorkerError, WorkerProcess

DEFAULT_CHUNK_ROWS = 32
# Logs of workers that crashed are kept for a while to debug them, then removed.
LOG_RETENTION_S = 7 * 24 * 3600


def default_worker_count() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def start_worker(
    argv: list[str], setup: list[tuple[str, dict]], *, log_dir: Path, start_timeout: float
) -> tuple[WorkerProcess, list[dict]]:
    """A worker process brought to the pool's state by replaying ``setup``, and the
    replies; the local pool and the Ray actors prepare their workers through this one."""
    worker = WorkerProcess(argv, log_dir=log_dir, start_timeout=start_timeout)
    replies = []
    try:
        for op, args in setup:
            header, _ = worker.request(op, args, timeout=start_timeout)
            replies.append(header)
    except WorkerError:
        worker.close()  # the error says what went wrong; its log adds nothing
        raise
    except BaseException:
        worker.kill()  # half set up: never hand it a request
        raise
    return worker, replies


class RowPool:
    """What the local and the Ray pool share: the context manager, one batch at a time,
    the row chunks (the same rows go together, whatever runs them) and the outputs put
    back in chunk order, so both give the same bytes."""

    n_workers: int
    worker_cpu_seconds: float
    _busy: threading.Lock

    def close(self) -> None:
        raise NotImplementedError

    def _map_rows(self, op, arrays, args, chunk_rows, on_chunk_done):
        raise NotImplementedError

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def map_rows(
        self,
        op: str,
        arrays: dict[str, np.ndarray],
        *,
        args: dict | None = None,
        chunk_rows: int = DEFAULT_CHUNK_ROWS,
        on_chunk_done: Callable[[int], None] | None = None,
    ) -> dict[str, np.ndarray]:
        """Run ``op`` on row chunks of ``arrays`` across the workers; outputs stacked by row."""
        with self._busy:
            return self._map_rows(op, arrays, args, chunk_rows, on_chunk_done)

    def _chunks(self, op: str, arrays: dict, chunk_rows: int) -> list[tuple[int, int]]:
        """``(start, stop)`` row ranges: about an even share a worker, ``chunk_rows`` at most."""
        n_rows = len(next(iter(arrays.values())))
        if n_rows == 0:
            raise ValueError(f"{op}: empty batch")
        rows = max(1, min(chunk_rows, math.ceil(n_rows / self.n_workers)))
        return [(start, min(start + rows, n_rows)) for start in range(0, n_rows, rows)]

    def _chunk_done(self, header: dict, rows: int, on_chunk_done) -> None:
        self.worker_cpu_seconds += float(header.get("cpu_seconds", 0.0))
        if on_chunk_done is not None:
            on_chunk_done(rows)

    @staticmethod
    def _stacked(results: list[dict]) -> dict[str, np.ndarray]:
        return {key: np.concatenate([r[key] for r in results]) for key in results[0]}


class WorkerPool(RowPool):
    """``workers`` processes started from ``argv``, each prepared by ``setup`` requests."""

    def __init__(
        self,
        argv: Callable[[int], list[str]],
        *,
        setup: list[tuple[str, dict]] | None = None,
        workers: int | None = None,
        timeout: float = 120.0,
        start_timeout: float = 180.0,
        max_retries: int = 2,
        log_dir: Path,
    ):
        if workers is not None and workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.n_workers = workers or default_worker_count()
        self.timeout = timeout
        self.start_timeout = start_timeout
        self.max_retries = max_retries
        self.restarts = 0
        self.worker_cpu_seconds = 0.0  # CPU the workers report spending on requests
        self.setup_replies: list[dict] = []
        self._argv = argv
        self._setup = list(setup or [])
        self._log_dir = Path(log_dir)
        _remove_old_logs(self._log_dir)
        self._slots: list[WorkerProcess | None] = [None] * self.n_workers
        self._lock = threading.Lock()  # bookkeeping inside one batch
        self._busy = threading.Lock()  # one batch at a time: a worker serves one request
        self._closed = False
        # Kills the processes even if the pool is dropped without close(), or at exit.
        self._finalizer = weakref.finalize(self, _kill_all, self._slots)

    # --- lifecycle ----------------------------------------------------------
    def _start(self, slot: int) -> WorkerProcess:
        if self._closed:
            raise RuntimeError("worker pool is closed")
        self._slots[slot] = None
        worker, replies = start_worker(
            self._argv(slot), self._setup, log_dir=self._log_dir, start_timeout=self.start_timeout
        )
        self._slots[slot] = worker
        if not self.setup_replies:
            self.setup_replies = replies
        return worker

    def _worker(self, slot: int) -> WorkerProcess:
        worker = self._slots[slot]
        if worker is None or not worker.alive:
            if worker is not None:
                # died between requests (killed, crashed while idle): a restart all the same
                worker.kill()
                with self._lock:
                    self.restarts += 1
            worker = self._start(slot)
        return worker

    def start(self) -> None:
        """Start every worker now (in parallel) instead of on first use."""
        with self._busy, ThreadPoolExecutor(self.n_workers) as executor:
            list(executor.map(self._worker, range(self.n_workers)))

    def pids(self) -> list[int]:
        return [w.pid for w in self._slots if w is not None and w.alive]

    def close(self) -> None:
        self._closed = True
        for slot, worker in enumerate(self._slots):
            if worker is not None:
                worker.close()
                self._slots[slot] = None
        self._finalizer.detach()

    # --- work ---------------------------------------------------------------
    def call(self, op: str, args: dict | None = None, arrays: dict | None = None, *, timeout=None):
        """One request on the first worker, restarted and retried if it crashes."""
        with self._busy:
            return self._call(op, args, arrays, timeout)

    def _call(self, op, args, arrays, timeout):
        for attempt in range(self.max_retries + 1):
            worker = self._worker(0)
            try:
                return worker.request(op, args, arrays, timeout=timeout or self.timeout)
            except WorkerCrashed:
                self._slots[0] = None
                self.restarts += 1
                if attempt == self.max_retries:
                    raise
        raise AssertionError("unreachable")

    def _map_rows(self, op, arrays, args, chunk_rows, on_chunk_done):
        chunks = self._chunks(op, arrays, chunk_rows)
        queue = deque(range(len(chunks)))
        attempts = [0] * len(chunks)
        results: list[dict | None] = [None] * len(chunks)
        failures: list[BaseException] = []

        def run(slot: int) -> None:
            while True:
                with self._lock:
                    if failures or not queue:
                        return
                    index = queue.popleft()
                start, stop = chunks[index]
                try:
                    worker = self._worker(slot)
                    header, out = worker.request(
                        op, args, {k: v[start:stop] for k, v in arrays.items()}, self.timeout
                    )
                except WorkerCrashed as crash:
                    with self._lock:
                        self._slots[slot] = None
                        self.restarts += 1
                        attempts[index] += 1
                        if attempts[index] > self.max_retries:
                            failures.append(crash)
                        else:
                            queue.appendleft(index)  # the next free worker redoes it
                    continue
                except BaseException as error:
                    with self._lock:
                        failures.append(error)
                    return
                with self._lock:
                    results[index] = out
                    self._chunk_done(header, stop - start, on_chunk_done)

        n_threads = min(self.n_workers, len(chunks))
        with ThreadPoolExecutor(n_threads) as executor:
            list(executor.map(run, range(n_threads)))
        if failures:
            raise failures[0]
        return self._stacked(results)


def _kill_all(slots: list) -> None:
    """Stop the workers of a pool nobody closed (garbage collection or interpreter exit)."""
    for worker in slots:
        if worker is not None:
            worker.close(timeout=2.0)


def _remove_old_logs(log_dir: Path) -> None:
    if not log_dir.is_dir():
        return
    cutoff = time.time() - LOG_RETENTION_S
    for log in log_dir.glob("worker-*.log"):
        try:
            if log.stat().st_mtime < cutoff:
                log.unlink()
        except OSError:
            pass  # another process removed it first
