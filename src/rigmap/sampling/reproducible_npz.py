"""Writing ``.npz`` files that are byte-identical for identical arrays, atomically; reading
them back with an error that names the file.

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

from rigmap.errors import RigmapError

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


class NpzFileError(RigmapError, ValueError):
    """A ``.npz`` file that is missing, truncated, bit-flipped or lacks an array."""


def read_npz(
    path: str | os.PathLike, required: tuple[str, ...] = (), *, what: str = "npz file"
) -> dict[str, np.ndarray]:
    """Every array of ``path`` (no pickles), read whole so a corrupted member shows here.

    zip's CRC-32 of each member is checked as it is read, so a flipped bit is found
    as well as a truncation. A missing file, a damaged one, or one without the
    ``required`` arrays raises ``NpzFileError`` naming the file and what to do.
    """
    path = Path(path)
    redo = "delete it and re-run the stage that writes it (dvc repro)"
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {key: data[key] for key in data.files}
    except FileNotFoundError:
        raise NpzFileError(f"{what} {path}: no such file; {redo}") from None
    except (zipfile.BadZipFile, EOFError, OSError, ValueError, KeyError) as error:
        reason = f"{type(error).__name__}: {error}"
        raise NpzFileError(
            f"{what} {path} is damaged or not a .npz file ({reason}); {redo}"
        ) from None
    missing = [key for key in required if key not in arrays]
    if missing:
        raise NpzFileError(f"{what} {path}: lacks the arrays {missing}; {redo}")
    return arrays
