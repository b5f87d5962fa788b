"""Blender workers as Ray actors: the :class:`~rigmap.rigs.blender.pool.WorkerPool` on a cluster.

``executor=ray`` swaps the local pool for this one under the same Rig protocol:
each actor starts one Blender worker process and replays the ``setup`` requests
(for a rig: ``load`` of its .blend), so it holds its loaded file for as long as it
lives. A batch is cut into the same row chunks as the local pool (by row index)
and the outputs are put back in chunk order, so the numbers are byte-identical
to the local pool's. A chunk whose actor dies (its node lost, the actor killed)
or whose Blender worker crashes is redone on a fresh actor, up to ``max_retries``
times a chunk. We use Ray's actors and ``ray.wait`` rather than our own
scheduler: a studio that already runs a Ray cluster gets its placement,
autoscaling and dashboard for free.

Every node must have rigmap, the Blender environment and the .blend at the same
paths as the driver (a shared file system or the same image), as with Slurm.
"""

from __future__ import annotations

import os
import socket
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path

from rigmap.errors import RigmapError
from rigmap.rigs.blender.pool import RowPool, start_worker
from rigmap.rigs.blender.worker_process import WorkerCrashed, WorkerProcess

# Chunks queued on one actor at a time: the next one waits in the actor while the
# current one runs, so the round trip through Ray is hidden behind Blender's work.
IN_FLIGHT_PER_ACTOR = 2
PROBE_TIMEOUT_S = 3.0


class RayUnavailableError(RigmapError, RuntimeError):
    """Ray is not installed, or no Ray cluster answers at the configured address."""


def _import_ray():
    try:
        import ray
    except ImportError as error:
        raise RayUnavailableError(
            "executor=ray needs the ray package, which is not installed in this environment: "
            "pip install -e '.[scale]' (make setup installs it), or use executor=local"
        ) from error
    return ray


def _probe(address: str, timeout: float) -> None:
    """Fail fast, naming the address, when nothing listens at a ``host:port`` Ray address."""
    target = address.removeprefix("ray://")
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise RayUnavailableError(
            f"executor=ray: address {address!r} is not host:port (or 'auto'/'local'/null)"
        )
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except OSError as error:
        raise RayUnavailableError(
            f"executor=ray: no Ray cluster answers at {address} ({error}); start one with "
            "`ray start --head` (or point executor.address / RAY_ADDRESS at yours), "
            "or use executor=local"
        ) from None


def ensure_ray(address: str | None = None, *, num_cpus: int | None = None):
    """The ``ray`` module, connected: to ``address`` (or ``RAY_ADDRESS``) or a new local head.

    A session already connected (``ray.init`` called by the caller, e.g. a test fixture
    or a Ray job) is used as it is.
    """
    ray = _import_ray()
    if ray.is_initialized():
        return ray
    address = address or os.environ.get("RAY_ADDRESS") or "local"
    if address not in ("local", "auto"):
        _probe(address, PROBE_TIMEOUT_S)
    kwargs = {"include_dashboard": False, "log_to_driver": False}
    if address == "local":
        kwargs["num_cpus"] = num_cpus
    try:
        ray.init(address=address, **kwargs)
    except ConnectionError as error:
        raise RayUnavailableError(
            f"executor=ray: could not connect to the Ray cluster at {address!r}: {error}; "
            "start one with `ray start --head`, or use executor=local"
        ) from error
    return ray


class BlenderActor:
    """Runs inside a Ray actor: one Blender worker process with the rig's file loaded."""

    def __init__(self, argv, setup, log_dir, start_timeout):
        self._argv = list(argv)
        self._setup = list(setup)
        self._log_dir = Path(log_dir)
        self._start_timeout = float(start_timeout)
        self.worker: WorkerProcess | None = None

    def start(self) -> dict:
        """Start the worker and replay the setup; its replies (the rig's description)."""
        self.worker, replies = start_worker(
            self._argv, self._setup, log_dir=self._log_dir, start_timeout=self._start_timeout
        )
        return {"replies": replies, "pid": self.worker.pid, "node": socket.gethostname()}

    def request(self, op, args, arrays, timeout):
        return self.worker.request(op, args, arrays, timeout=timeout)

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()
            self.worker = None


class RayWorkerPool(RowPool):
    """``actors`` Ray actors each holding a started, set-up worker; the local pool's interface."""

    def __init__(
        self,
        argv: Callable[[int], list[str]],
        *,
        setup: list[tuple[str, dict]] | None = None,
        actors: int = 2,
        address: str | None = None,
        num_cpus_per_actor: float = 1.0,
        timeout: float = 120.0,
        start_timeout: float = 180.0,
        max_retries: int = 2,
        log_dir: Path,
    ):
        if isinstance(actors, bool) or not isinstance(actors, int) or actors < 1:
            raise ValueError(f"executor=ray: actors must be a whole number >= 1, got {actors!r}")
        self._ray = ensure_ray(address, num_cpus=actors)
        self.n_workers = actors
        self.timeout = timeout
        self.start_timeout = start_timeout
        self.max_retries = max_retries
        self.restarts = 0
        self.worker_cpu_seconds = 0.0
        self.setup_replies: list[dict] = []
        self.actor_info: list[dict | None] = [None] * actors
        self._argv = argv
        self._setup = list(setup or [])
        self._log_dir = Path(log_dir)
        self._remote = self._ray.remote(num_cpus=num_cpus_per_actor, max_restarts=0)(BlenderActor)
        self._actors: list = [None] * actors
        self._busy = threading.Lock()
        self._closed = False

    # --- lifecycle ----------------------------------------------------------
    def _start(self, slot: int):
        if self._closed:
            raise RuntimeError("worker pool is closed")
        actor = self._remote.remote(
            self._argv(slot), self._setup, str(self._log_dir), self.start_timeout
        )
        try:
            info = self._ray.get(actor.start.remote())
        except BaseException as error:
            self._ray.kill(actor)
            raise _cause(self._ray, error) from None
        self._actors[slot] = actor
        self.actor_info[slot] = info
        if not self.setup_replies:
            self.setup_replies = info["replies"]
        return actor

    def _actor(self, slot: int):
        return self._actors[slot] if self._actors[slot] is not None else self._start(slot)

    def _replace(self, slot: int) -> None:
        """Drop a lost actor; the next use of the slot starts a fresh one."""
        actor, self._actors[slot] = self._actors[slot], None
        if actor is not None:
            try:
                self._ray.kill(actor)
            except Exception:  # already gone with its node
                pass
        self.restarts += 1

    def start(self) -> None:
        """Start every actor now (their Blender workers load in parallel)."""
        with self._busy:
            refs, actors = [], []
            for slot in range(self.n_workers):
                if self._actors[slot] is None:
                    actor = self._remote.remote(
                        self._argv(slot), self._setup, str(self._log_dir), self.start_timeout
                    )
                    refs.append(actor.start.remote())
                    actors.append((slot, actor))
            try:
                infos = self._ray.get(refs)
            except BaseException as error:
                for _, actor in actors:
                    self._ray.kill(actor)
                raise _cause(self._ray, error) from None
            for (slot, actor), info in zip(actors, infos, strict=True):
                self._actors[slot] = actor
                self.actor_info[slot] = info
            if not self.setup_replies and infos:
                self.setup_replies = infos[0]["replies"]

    def pids(self) -> list[int]:
        return [i["pid"] for a, i in zip(self._actors, self.actor_info, strict=True) if a and i]

    def close(self) -> None:
        self._closed = True
        for slot, actor in enumerate(self._actors):
            if actor is not None:
                try:
                    self._ray.get(actor.close.remote(), timeout=10)
                except Exception:
                    pass
                try:
                    self._ray.kill(actor)
                except Exception:
                    pass
                self._actors[slot] = None

    # --- work ---------------------------------------------------------------
    def call(self, op: str, args: dict | None = None, arrays: dict | None = None, *, timeout=None):
        """One request on the first actor, on a fresh actor if it is lost."""
        with self._busy:
            for attempt in range(self.max_retries + 1):
                actor = self._actor(0)
                ref = actor.request.remote(op, args, arrays, timeout or self.timeout)
                try:
                    return self._ray.get(ref)
                except BaseException as error:
                    cause = _cause(self._ray, error)
                    if not _lost(self._ray, cause) or attempt == self.max_retries:
                        raise cause from None
                    self._replace(0)
        raise AssertionError("unreachable")

    def _map_rows(self, op, arrays, args, chunk_rows, on_chunk_done):
        ray = self._ray
        chunks = self._chunks(op, arrays, chunk_rows)  # the local pool's chunking
        queue = deque(range(len(chunks)))
        attempts = [0] * len(chunks)
        results: list[dict | None] = [None] * len(chunks)
        in_flight: dict = {}  # ObjectRef -> (slot, chunk index, the actor it went to)
        load = [0] * self.n_workers

        def submit(slot: int) -> None:
            while queue and load[slot] < IN_FLIGHT_PER_ACTOR:
                index = queue.popleft()
                start, stop = chunks[index]
                try:
                    actor = self._actor(slot)
                except BaseException:
                    queue.appendleft(index)
                    raise
                part = {k: v[start:stop] for k, v in arrays.items()}
                ref = actor.request.remote(op, args, part, self.timeout)
                in_flight[ref] = (slot, index, actor)
                load[slot] += 1

        try:
            for slot in range(self.n_workers):
                submit(slot)
            while in_flight:
                (ref,), _ = ray.wait(list(in_flight), num_returns=1)
                slot, index, actor = in_flight.pop(ref)
                load[slot] -= 1
                try:
                    header, out = ray.get(ref)
                except BaseException as error:
                    cause = _cause(ray, error)
                    if not _lost(ray, cause):
                        raise cause from None
                    attempts[index] += 1
                    if attempts[index] > self.max_retries:
                        raise WorkerCrashed(
                            f"{op}: rows {chunks[index][0]}-{chunks[index][1] - 1} failed on "
                            f"{attempts[index]} Ray actors; last: {cause}"
                        ) from cause
                    # the actor (or its Blender worker) is gone with whatever it held:
                    # its other chunks come back failed too and are requeued the same way
                    if self._actors[slot] is actor:  # not yet replaced by a sibling chunk
                        self._replace(slot)
                    queue.appendleft(index)
                    submit(slot)
                    continue
                results[index] = out
                self._chunk_done(header, chunks[index][1] - chunks[index][0], on_chunk_done)
                submit(slot)
        except BaseException:
            for ref in in_flight:
                try:
                    ray.cancel(ref)
                except Exception:  # already finished, or its actor is gone
                    pass
            raise
        return self._stacked(results)


def _cause(ray, error: BaseException) -> BaseException:
    """The exception raised inside the actor (a WorkerError, a WorkerCrashed), else ``error``."""
    if isinstance(error, ray.exceptions.RayTaskError) and error.cause is not None:
        return error.cause
    return error


def _lost(ray, error: BaseException) -> bool:
    """The actor or its Blender worker is gone: the chunk is redone on a fresh actor."""
    return isinstance(error, WorkerCrashed | ray.exceptions.RayActorError)
