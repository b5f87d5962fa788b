"""The on-disk cache of generated rigs and rig descriptions.

Lives in ``$RIGMAP_CACHE/blender`` (default ``~/.cache/rigmap/blender``). Every
file is written atomically, and a file lock stops two processes generating the
same rig at once.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import tempfile
from pathlib import Path

CACHE_ENV_VAR = "RIGMAP_CACHE"


def cache_dir() -> Path:
    root = os.environ.get(CACHE_ENV_VAR)
    base = Path(root).expanduser() if root else Path.home() / ".cache" / "rigmap"
    folder = base / "blender"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@contextlib.contextmanager
def file_lock(path: Path):
    """Hold an exclusive lock on ``path`` (created if missing) for the ``with`` body."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def write_json_atomic(path: Path, data) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, temp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            json.dump(data, handle)
        os.replace(temp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temp)
        raise


def read_json(path: Path):
    """The JSON in ``path``, or ``None`` when it is missing or unreadable (a stale cache)."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None
