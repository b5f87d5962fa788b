"""Data files as MLflow datasets, so a run names the corpus and samples its numbers came from.

Each file becomes an input of the run (``log_inputs``) with a context (``training``,
``test`` or ``samples``, the ``mlflow.data.context`` tag). Its digest is DVC's hash of
the file: DVC 3 (``hash: md5`` in dvc.lock) hashes a file as the plain md5 of its bytes,
the value dvc.lock gives a file output such as ``data/<rig>/samples/<sampler>.npz`` and
the folder manifest (``.dir``) gives each file of ``data/<rig>/corpus``. We compute it
from the bytes, not from dvc.lock: the lock of a folder holds only the folder's ``.dir``
hash, and a file changed outside DVC must not show DVC's older hash.

Only metadata is logged (no copy of the data, no array loaded): a parquet file's columns
and row count come from its footer, an npz file's array shapes from their headers.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mlflow.entities import Dataset as DatasetEntity
from mlflow.entities import DatasetInput, InputTag
from mlflow.utils.mlflow_tags import MLFLOW_DATASET_CONTEXT

#: the contexts rigmap gives its inputs (ours): what a run learned from, what it was scored
#: on, and the extra samples a network learned from
CONTEXTS = ("training", "test", "samples")
_CHUNK = 1 << 20


@dataclass(frozen=True)
class DataFile:
    """One file a run read, the dataset name it is shown under and its context."""

    path: Path
    name: str
    context: str

    def __post_init__(self) -> None:
        if self.context not in CONTEXTS:
            raise ValueError(
                f"dataset {self.name!r}: context {self.context!r} is not one of {CONTEXTS}"
            )
        object.__setattr__(self, "path", Path(self.path))


def file_md5(path: str | Path) -> str:
    """The md5 of the file's bytes: DVC 3's hash of a file (read in 1 MiB pieces)."""
    digest = hashlib.md5(usedforsecurity=False)
    with open(path, "rb") as handle:
        while piece := handle.read(_CHUNK):
            digest.update(piece)
    return digest.hexdigest()


def dataset_input(file: DataFile, digest: str | None = None) -> DatasetInput:
    """``file`` as a run input: its name, DVC md5 (``digest``, computed when None), local
    source, and what its footer or headers say; one line naming the file if it is missing."""
    from mlflow.data.dataset_source_registry import get_dataset_source_from_json
    from mlflow.data.meta_dataset import MetaDataset

    if not file.path.is_file():
        raise FileNotFoundError(f"{file.path}: dataset {file.name!r} ({file.context}) is missing")
    schema, profile = _describe(file.path)
    source = get_dataset_source_from_json(
        json.dumps({"uri": file.path.resolve().as_uri()}), "local"
    )
    described = MetaDataset(
        source, name=file.name, digest=digest or file_md5(file.path), schema=schema
    ).to_dict()
    entity = DatasetEntity(
        name=described["name"],
        digest=described["digest"],
        source_type=described["source_type"],
        source=described["source"],
        schema=described.get("schema"),
        profile=json.dumps(profile),
    )
    return DatasetInput(entity, [InputTag(MLFLOW_DATASET_CONTEXT, file.context)])


def dataset_inputs(groups: Mapping[str, Sequence[DataFile]]) -> dict[str, list[DatasetInput]]:
    """The inputs of each group of files; a file listed twice (the training frames scored as
    the test split) is hashed and logged once, in the first group listing it."""
    seen: set[Path] = set()
    inputs: dict[str, list[DatasetInput]] = {}
    for group, files in groups.items():
        inputs[group] = []
        for file in files:
            key = file.path.resolve()
            if key not in seen:
                seen.add(key)
                inputs[group].append(dataset_input(file))
    return inputs


# --------------------------------------------------------------------------- what a file holds
def _describe(path: Path) -> tuple[Any, dict[str, Any]]:
    """(MLflow schema or None, profile) of a parquet or npz file, from metadata only."""
    if path.suffix == ".parquet":
        return _parquet_description(path)
    if path.suffix == ".npz":
        return None, {"arrays": _npz_shapes(path)}
    return None, {"bytes": path.stat().st_size}


def _parquet_description(path: Path) -> tuple[Any, dict[str, Any]]:
    import pyarrow.parquet as pq
    from mlflow.types import ColSpec, Schema

    metadata = pq.read_metadata(path)
    arrow = metadata.schema.to_arrow_schema()
    types = [_mlflow_type(field.type) for field in arrow]
    schema = None
    if all(t is not None for t in types):  # a partial schema would misstate the file
        schema = Schema([ColSpec(t, field.name) for t, field in zip(types, arrow, strict=True)])
    return schema, {"num_rows": metadata.num_rows, "num_columns": len(arrow)}


def _mlflow_type(arrow_type) -> str | None:
    """The MLflow column type of an arrow type, or None for one MLflow has no name for."""
    import pyarrow as pa

    if pa.types.is_dictionary(arrow_type):
        arrow_type = arrow_type.value_type
    if pa.types.is_float64(arrow_type):
        return "double"
    if pa.types.is_floating(arrow_type):
        return "float"
    if pa.types.is_integer(arrow_type):
        return "long" if arrow_type.bit_width > 32 else "integer"
    if pa.types.is_boolean(arrow_type):
        return "boolean"
    if pa.types.is_string(arrow_type) or pa.types.is_large_string(arrow_type):
        return "string"
    if pa.types.is_timestamp(arrow_type):
        return "datetime"
    return None


def _npz_shapes(path: Path) -> dict[str, list[int] | None]:
    """Each array's shape from its ``.npy`` header (None for a header version numpy reads
    with no public function); the data is not read."""
    from numpy.lib import format as npy

    readers = {(1, 0): npy.read_array_header_1_0, (2, 0): npy.read_array_header_2_0}
    shapes: dict[str, list[int] | None] = {}
    with zipfile.ZipFile(path) as archive:
        for member in archive.namelist():
            if not member.endswith(".npy"):
                continue
            with archive.open(member) as handle:
                reader = readers.get(npy.read_magic(handle))
                shape = None if reader is None else list(reader(handle)[0])
            shapes[member[: -len(".npy")]] = shape
    return shapes
