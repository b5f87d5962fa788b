"""A fitted model on disk: a payload file plus the JSON that names it and its hash.

Every regressor saves into a folder as ``<name>.json`` and ``<name><suffix>``
(``gpr.npz``, ``nn.npz``, …), ``<name>`` being the model's one name (its config
choice). The payload is written first and the JSON last, with the payload's
SHA-256 in it, so the JSON is the commit: a save interrupted between the two
leaves a payload whose hash the old JSON does not match, which loading reports
instead of mixing two models. Both files are written atomically by
:mod:`rigmap.store` (readable by everyone). Nothing in a file names code to
import: the class is chosen by the caller, or among the known regressor
classes by the file's name.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rigmap.regression.errors import ModelFileError
from rigmap.store import json_ready, write_bytes_atomic, write_text_atomic

FORMAT_VERSION = 1


def write_model_files(
    folder: str | os.PathLike, stem: str, payload: bytes, payload_suffix: str, meta: dict
) -> Path:
    """Payload first, then ``<stem>.json`` naming it and its hash (the JSON is the commit)."""
    folder = Path(folder)
    payload_path = folder / f"{stem}{payload_suffix}"
    write_bytes_atomic(payload_path, payload)
    meta = {**meta, "payload": payload_path.name, "payload_sha256": _sha256(payload)}
    write_text_atomic(folder / f"{stem}.json", json.dumps(meta, indent=2) + "\n")
    return folder


def read_model_files(
    folder: str | os.PathLike, stem: str, kind: str, *, legacy: Sequence[str] = ()
) -> tuple[dict, bytes]:
    """The JSON metadata and the verified payload bytes of a saved model.

    ``legacy`` names the model once had (e.g. ``network`` for ``nn``): a folder
    written under such a name, as ``<legacy>.json`` with that ``kind``, loads too.
    """
    folder = Path(folder)
    stem, kind = _present_name(folder, stem, kind, legacy)
    meta_path = folder / f"{stem}.json"
    try:
        meta = json.loads(meta_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ModelFileError(f"{meta_path}: not valid JSON ({error})") from None
    if meta.get("kind") != kind:
        raise ModelFileError(
            f"{meta_path}: field 'kind' is {meta.get('kind')!r}, expected {kind!r}"
        )
    if not isinstance(meta, dict):
        raise ModelFileError(f"{meta_path}: expected a JSON object, got {type(meta).__name__}")
    payload_path = payload_inside(folder, meta.get("payload"), meta_path)
    if not payload_path.is_file():
        raise ModelFileError(f"{meta_path}: its data file {payload_path.name!r} is missing")
    payload = payload_path.read_bytes()
    if _sha256(payload) != meta.get("payload_sha256"):
        raise ModelFileError(
            f"{payload_path}: contents do not match the hash in {meta_path.name} "
            "(an interrupted save, or files from two different models)"
        )
    return meta, payload


def payload_inside(folder: Path, name: Any, meta_path: Path) -> Path:
    """The payload file ``name`` of ``meta_path``, resolved; refused if it leaves ``folder``."""
    if not isinstance(name, str) or not name:
        raise ModelFileError(f"{meta_path}: field 'payload' must be a file name, got {name!r}")
    resolved, root = (folder / name).resolve(), folder.resolve()
    if not resolved.is_relative_to(root) or resolved == root:
        raise ModelFileError(
            f"{meta_path}: payload {name!r} leads to {resolved}, outside the model folder "
            f"{root}; the model is refused"
        )
    return resolved


def _present_name(folder: Path, stem: str, kind: str, legacy: Sequence[str]) -> tuple[str, str]:
    for name in (stem, *legacy):
        if (folder / f"{name}.json").is_file():
            return (stem, kind) if name == stem else (name, name)
    present = sorted(p.name for p in folder.glob("*.json")) if folder.is_dir() else []
    raise ModelFileError(
        f"{folder}: no {kind} model here (expected {stem}.json"
        f"{'; found ' + ', '.join(present) if present else ''})"
    )


def has_model_file(folder: str | os.PathLike, names: Iterable[str]) -> bool:
    """Whether ``folder`` holds ``<name>.json`` for one of ``names``."""
    return any((Path(folder) / f"{name}.json").is_file() for name in names)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)  # every member's zip time: the bytes never hold a clock


def arrays_to_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An npz (uncompressed, no pickles) whose bytes depend only on ``arrays`` and their
    order, so a model saved twice from the same fit is the same file."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, mode="w", compression=zipfile.ZIP_STORED) as archive:
        for name, value in arrays.items():
            member = zipfile.ZipInfo(f"{name}.npy", date_time=ZIP_EPOCH)
            with archive.open(member, mode="w", force_zip64=True) as out:
                np.lib.format.write_array(out, np.asanyarray(value), allow_pickle=False)
    return buffer.getvalue()


def arrays_from_bytes(payload: bytes, where: str, names: Sequence[str]) -> dict[str, np.ndarray]:
    """The arrays ``names`` of an npz payload; never unpickles (a pickle is refused)."""
    try:
        data = np.load(io.BytesIO(payload), allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
        raise ModelFileError(
            f"{where}: not an npz of plain arrays ({_first_line(error)})"
        ) from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise ModelFileError(f"{where}: not an npz of plain arrays (one bare array)")
    with data:
        missing = [n for n in names if n not in data.files]
        if missing:
            raise ModelFileError(f"{where}: arrays {missing} are missing (have {data.files})")
        try:
            return {n: data[n] for n in names}
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
            raise ModelFileError(f"{where}: unreadable array ({_first_line(error)})") from None


def _first_line(error: BaseException) -> str:
    return (str(error).strip().splitlines() or [type(error).__name__])[0]


def check_arrays(
    arrays: Mapping[str, np.ndarray], schema: Mapping[str, tuple], where: str, dims=None
) -> dict[str, int]:
    """Refuse arrays of the wrong kind or shape; the sizes the named dimensions took.

    ``schema``: name → ``(kind, shape)``, ``kind`` a numpy dtype kind (``"f"`` means
    float64), ``shape`` of ints or dimension names that must agree across arrays."""
    dims = dict(dims or {})
    for name, (kind, shape) in schema.items():
        value = arrays[name]
        if value.dtype.kind != kind or (kind == "f" and value.dtype != np.float64):
            raise ModelFileError(
                f"{where}: array {name!r} has dtype {value.dtype}, expected "
                f"{'float64' if kind == 'f' else 'kind ' + kind}"
            )
        if value.ndim != len(shape):
            raise ModelFileError(
                f"{where}: array {name!r} has shape {value.shape}, expected {shape}"
            )
        for axis, (size, want) in enumerate(zip(value.shape, shape, strict=True)):
            want = dims.setdefault(want, size) if isinstance(want, str) else want
            if size != want:
                raise ModelFileError(
                    f"{where}: array {name!r} has shape {value.shape}, expected {shape} "
                    f"(axis {axis} should be {want})"
                )
    return dims


def params_for_file(params: dict[str, Any]) -> dict[str, Any]:
    """Hyper-parameters as plain JSON: kernels by ``to_dict``, arrays and tuples as lists."""
    from rigmap.regression.kernels import Kernel

    return {
        name: value.to_dict() if isinstance(value, Kernel) else json_ready(value)
        for name, value in params.items()
    }


def params_from_file(params: dict[str, Any], kernel_params: Sequence[str] = ()) -> dict[str, Any]:
    """Inverse of :func:`params_for_file` for the parameters named in ``kernel_params``."""
    from rigmap.regression.kernels import kernel_from_dict

    restored = dict(params)
    for name in kernel_params:
        if isinstance(restored.get(name), dict):
            restored[name] = kernel_from_dict(restored[name])
    return restored
