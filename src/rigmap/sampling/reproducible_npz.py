"""Writing ``.npz`` files that are byte-identical for identical arrays, atomically.

DVC and the resume check compare files by content, so the archive must not
depend on when it was written: every member gets the same fixed zip timestamp
(``np.savez`` leaves that to the Python version's ``zipfile``). Members are
stored uncompressed in the given key order; no pickles, so ``np.load`` works
with ``allow_pickle=False``.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)  # the earliest time a zip entry can hold


def save_npz_atomically(path: str | os.PathLike, arrays: Mapping[str, object]) -> Path:
    """Write ``arrays`` to ``path`` through a temporary sibling file and ``os.replace``.

    A crash leaves either the old file or the new one, never half of one.
    """
    path = Path(path)
    if path.suffix != ".npz":
        raise ValueError(f"npz output must end in .npz, got {str(path)!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as file:
            with zipfile.ZipFile(file, mode="w", compression=zipfile.ZIP_STORED) as archive:
                for key, value in arrays.items():
                    member = zipfile.ZipInfo(f"{key}.npy", date_time=ZIP_EPOCH)
                    member.compress_type = zipfile.ZIP_STORED
                    with archive.open(member, mode="w", force_zip64=True) as out:
                        np.lib.format.write_array(out, np.asanyarray(value), allow_pickle=False)
            file.flush()
            os.fsync(file.fileno())
        os.chmod(temporary, 0o644)  # mkstemp makes 0600; sample files are for everyone
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def leftover_temporaries(path: str | os.PathLike) -> list[Path]:
    """Temporary files a killed ``save_npz_atomically(path, …)`` may have left."""
    path = Path(path)
    return sorted(path.parent.glob(f".{path.name}.*.tmp"))
