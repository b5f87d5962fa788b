"""The on-disk cache of generated rigs and rig descriptions.

Lives in ``$RIGMAP_CACHE/blender`` (default ``~/.cache/rigmap/blender``). Every
file is written atomically, and a file lock stops two processes generating the
same rig at once. A generated file's SHA-256 is recorded in its ``.json``
sidecar; a cached file that is truncated, bit-flipped or has no record
(:func:`cached_file_ok`) is removed and generated again instead of failing
every load until someone deletes it by hand.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import tempfile
from pathlib import Path

from rigmap.store.layout import Layout


def cache_dir() -> Path:
    """:meth:`rigmap.store.Layout.blender_cache`, made if missing."""
    folder = Layout.blender_cache()
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


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def cached_file_ok(path: Path) -> bool:
    """``path`` exists and has the SHA-256 its sidecar ``.json`` recorded when it was made."""
    path = Path(path)
    info = read_json(path.with_suffix(".json"))
    if not path.is_file() or not isinstance(info, dict) or "sha256" not in info:
        return False
    return file_sha256(path) == info["sha256"]


def discard_cached(path: Path) -> None:
    """Remove a cached file and its sidecar (a corrupted or unrecorded entry)."""
    for stale in (Path(path), Path(path).with_suffix(".json")):
        stale.unlink(missing_ok=True)
