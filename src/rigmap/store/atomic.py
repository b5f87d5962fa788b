"""Atomic writes: a temporary sibling, flushed, then renamed over the target.

A writer killed mid-way leaves at most a hidden temporary file (removed on any Python
exception) and never a truncated target, so a DVC stage that dies can simply be re-run.
Files are made readable by everyone (``mkstemp`` creates them 0600).

Two writers of one output (two runs of one stage, a user's command beside DVC): each fills
its own temporary, then swaps it in holding an exclusive ``flock`` on the target's parent
folder (a lock on the folder itself, so no lock file is left among the outputs). So one
wins whole and the other waits its turn; a file where a folder is (or the reverse) is an
``OutputConflictError`` naming the path, never a mixed file/folder.
"""

from __future__ import annotations

import errno
import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError

FILE_MODE = 0o644
FOLDER_MODE = 0o755


class OutputConflictError(RigmapError, FileExistsError):
    """The target is a folder where a file is written, or a file where a folder is."""


@contextmanager
def _swap_lock(parent: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``parent`` (its own inode) while an output is swapped in."""
    try:
        import fcntl
    except ImportError:  # no flock (Windows): the rename alone, as before
        yield
        return
    handle = os.open(parent, os.O_RDONLY)
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
        except OSError as error:  # a file system without flock: the rename alone, as before
            if error.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
                raise
        yield
    finally:
        os.close(handle)  # closing releases the lock


@contextmanager
def atomic_file(path: str | os.PathLike, *, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on a clean exit it replaces ``path``.

    For writers that want a file name (``np.savez``, ``fig.savefig``, ``pq.write_table``);
    ``suffix`` keeps the extension such writers look at (``.png``, ``.npz``).
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{out.name}.", suffix=suffix, dir=out.parent)
    os.close(handle)
    try:
        yield Path(temporary)
        with open(temporary, "rb") as stream:
            os.fsync(stream.fileno())
        os.chmod(temporary, FILE_MODE)
        with _swap_lock(out.parent):
            if out.is_dir() and not out.is_symlink():
                raise OutputConflictError(
                    f"{out}: a folder is there (another writer's output?); not replacing it "
                    "with a file"
                )
            os.replace(temporary, out)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    out = Path(path)
    with atomic_file(out) as temporary:
        temporary.write_bytes(data)
    return out


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically; returns the path."""
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_json_atomic(path: str | os.PathLike, data: Any, *, indent: int | None = 2) -> Path:
    """Write ``data`` as strict JSON (sorted keys, no NaN) plus a newline, atomically."""
    text = json.dumps(data, indent=indent, sort_keys=True, allow_nan=False)
    return write_text_atomic(path, text + "\n")


def write_folder_atomic(folder: str | os.PathLike, fill: Callable[[Path], None]) -> Path:
    """Fill a hidden sibling folder with ``fill(staging)``, then rename it to ``folder``.

    An existing ``folder`` is replaced only once the new one is complete. A writer killed
    mid-way leaves at most a hidden ``.<name>.<pid>.*`` sibling, which the next write of
    the same folder removes once its process is gone.
    """
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    _remove_abandoned(folder)
    prefix = f".{folder.name}.{os.getpid()}."
    staging = Path(tempfile.mkdtemp(prefix=prefix, suffix=".tmp", dir=folder.parent))
    retired = None
    try:
        fill(staging)
        staging.chmod(FOLDER_MODE)
        with _swap_lock(folder.parent):  # another writer of `folder` waits here
            if folder.exists() or folder.is_symlink():
                if not folder.is_dir() or folder.is_symlink():
                    raise OutputConflictError(
                        f"{folder}: a file is there (another writer's output?); not "
                        "replacing it with a folder"
                    )
                retired = Path(tempfile.mkdtemp(prefix=prefix, suffix=".old", dir=folder.parent))
                os.replace(folder, retired / folder.name)
            os.replace(staging, folder)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        if retired is not None and not folder.exists() and (retired / folder.name).exists():
            os.replace(retired / folder.name, folder)  # put the old output back
        raise
    finally:
        if retired is not None:
            shutil.rmtree(retired, ignore_errors=True)
    return folder


def _remove_abandoned(folder: Path) -> None:
    pattern = re.compile(rf"^\.{re.escape(folder.name)}\.(\d+)\..*\.(tmp|old)$")
    for candidate in folder.parent.iterdir():
        match = pattern.match(candidate.name)
        if match and candidate.is_dir() and not _process_alive(int(match.group(1))):
            shutil.rmtree(candidate, ignore_errors=True)


def _process_alive(pid: int) -> bool:
    if pid == os.getpid():
        return False  # our own leftovers can only be from an earlier, failed call
    try:
        os.kill(pid, 0)  # signal 0: only asks whether the process exists
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
