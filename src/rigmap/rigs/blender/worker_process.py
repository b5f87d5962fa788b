"""One Blender worker process seen from rigmap: start it, send a request, get a reply.

Every read and write has a deadline (``select`` on the pipe), so a hung worker
is a :class:`RequestTimeout`, a dead one a :class:`WorkerCrashed`; in both cases
the process is killed before the error is raised. An error *inside* a request
(a bad bone name, a missing file) comes back as :class:`WorkerError` and leaves
the worker running.
"""

from __future__ import annotations

import itertools
import os
import select
import subprocess
import time
from pathlib import Path

from rigmap.errors import RigmapError
from rigmap.rigs.blender.in_blender import protocol

_COUNTER = itertools.count()


class WorkerCrashed(RuntimeError):
    """The worker died, closed its output, or sent bytes that are not a frame."""


class RequestTimeout(WorkerCrashed):
    """The worker did not answer in time; it has been killed."""


class WorkerError(RigmapError, RuntimeError):
    """The worker ran the request and reported an exception."""

    def __init__(self, message: str, remote_traceback: str = ""):
        super().__init__(message)
        self.remote_traceback = remote_traceback


class WorkerProcess:
    """A started worker that has said hello; ``request`` talks to it."""

    def __init__(
        self,
        argv: list[str],
        *,
        log_dir: Path,
        start_timeout: float = 120.0,
        env: dict | None = None,
    ):
        log_dir.mkdir(parents=True, exist_ok=True)
        self.log_path = log_dir / f"worker-{os.getpid()}-{next(_COUNTER)}.log"
        self._log = open(self.log_path, "ab")  # closed in kill(): lives as long as the process
        self._pending = b""
        self.argv = argv
        try:
            self.process = subprocess.Popen(
                argv,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self._log,
                bufsize=0,
                env=env,
                start_new_session=True,  # a Ctrl-C reaches rigmap, which then stops the workers
            )
        except OSError as error:
            self._log.close()
            raise WorkerCrashed(f"could not start worker {argv[0]}: {error}") from error
        os.set_blocking(self.process.stdin.fileno(), False)
        try:
            self.hello = self._read_hello(time.monotonic() + start_timeout)
        except BaseException:
            self.kill()
            raise

    @property
    def pid(self) -> int:
        return self.process.pid

    @property
    def alive(self) -> bool:
        return self.process.poll() is None

    # --- requests ---------------------------------------------------------
    def request(
        self, op: str, args: dict | None = None, arrays: dict | None = None, timeout: float = 120.0
    ) -> tuple[dict, dict]:
        if self.process.stdin is None or self.process.stdin.closed or not self.alive:
            # killed after an earlier failure (its pipes closed): a crash, not a ValueError
            raise WorkerCrashed(self._crash_message(op, "it is no longer running"))
        deadline = time.monotonic() + timeout
        frame = protocol.encode_frame({"op": op, "args": args or {}}, arrays)
        try:
            self._write_all(frame, deadline, op)
            reply = protocol.read_frame(lambda n: self._read_exact(n, deadline, op))
        except RequestTimeout:
            self.kill()
            raise
        except (OSError, protocol.ProtocolError) as error:
            self.kill()
            raise WorkerCrashed(self._crash_message(op, str(error))) from error
        if reply is None:
            self.kill()
            raise WorkerCrashed(self._crash_message(op, "it closed its output (died?)"))
        header, out = reply
        if not header.get("ok"):
            raise WorkerError(
                f"Blender worker failed on {op!r}: {header.get('error')}",
                header.get("traceback", ""),
            )
        return header, out

    def _crash_message(self, op: str, what: str) -> str:
        code = self.process.poll()
        status = f"exit code {code}" if code is not None else "still running"
        return (
            f"Blender worker pid {self.pid} failed during {op!r}: {what} ({status}); "
            f"log {self.log_path}:\n{self.log_tail()}"
        )

    def _read_hello(self, deadline: float) -> dict:
        """Skip whatever a Blender executable prints before the worker takes over stdout."""
        buffer = b""
        while protocol.MAGIC not in buffer:
            chunk = self._read_some(deadline, "start-up")
            if not chunk:
                raise WorkerCrashed(
                    self._crash_message("start-up", "it exited before saying hello")
                )
            buffer += chunk
        self._pending = buffer[buffer.index(protocol.MAGIC) :]
        frame = protocol.read_frame(lambda n: self._read_exact(n, deadline, "start-up"))
        if frame is None or frame[0].get("op") != "hello":
            raise WorkerCrashed(self._crash_message("start-up", "its first frame was not hello"))
        hello = frame[0]
        if hello.get("protocol") != protocol.PROTOCOL_VERSION:
            raise WorkerCrashed(
                f"worker speaks protocol {hello.get('protocol')}, rigmap "
                f"{protocol.PROTOCOL_VERSION}: reinstall the package"
            )
        return hello

    # --- pipe I/O with deadlines --------------------------------------------
    def _read_some(self, deadline: float, op: str) -> bytes:
        fd = self.process.stdout.fileno()
        remaining = deadline - time.monotonic()
        if remaining <= 0 or not select.select([fd], [], [], remaining)[0]:
            raise RequestTimeout(self._timeout_message(op))
        return os.read(fd, 1 << 20)

    def _read_exact(self, n: int, deadline: float, op: str) -> bytes:
        data, self._pending = self._pending[:n], self._pending[n:]
        chunks = [data]
        got = len(data)
        while got < n:
            chunk = self._read_some(deadline, op)
            if not chunk:
                break
            if got + len(chunk) > n:
                chunk, self._pending = chunk[: n - got], chunk[n - got :]
            chunks.append(chunk)
            got += len(chunk)
        return b"".join(chunks)

    def _write_all(self, data: bytes, deadline: float, op: str) -> None:
        fd = self.process.stdin.fileno()
        view = memoryview(data)
        while view:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not select.select([], [fd], [], remaining)[1]:
                raise RequestTimeout(self._timeout_message(op))
            try:
                view = view[os.write(fd, view[: 1 << 20]) :]
            except BlockingIOError:
                continue

    def _timeout_message(self, op: str) -> str:
        return f"Blender worker pid {self.pid} did not answer {op!r} in time; killed it"

    # --- shutting down ------------------------------------------------------
    def log_tail(self, chars: int = 3000) -> str:
        try:
            text = self.log_path.read_bytes()[-chars:].decode("utf-8", "replace")
        except OSError:
            return "(no log)"
        return text or "(empty log)"

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        self._close_pipes()

    def close(self, timeout: float = 5.0) -> None:
        """Ask the worker to exit; kill it if it does not within ``timeout`` seconds."""
        if self.process.poll() is None:
            try:
                self.request("exit", timeout=timeout)
            except (WorkerCrashed, WorkerError, OSError):
                pass
            try:
                self.process.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                pass
        self.kill()
        self.log_path.unlink(missing_ok=True)  # a clean stop: the log holds nothing to debug

    def _close_pipes(self) -> None:
        for stream in (self.process.stdin, self.process.stdout):
            if stream is not None and not stream.closed:
                stream.close()
        if not self._log.closed:
            self._log.close()
