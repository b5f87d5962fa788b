"""Parquet tables that carry their own JSON metadata (corpus, poses, mapped controls).

The metadata lives in the parquet schema under one key per kind of file, so a file
says what it is (format, rig, split, column layout) without a sidecar. Writing is
deterministic (sorted keys, no timestamps, zstd) and atomic.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from rigmap.errors import RigmapError
from rigmap.store.atomic import atomic_file


class TableFileError(RigmapError, ValueError):
    """A table file is unreadable, or not the kind of file its reader expects."""


def write_table_file(
    path: str | os.PathLike,
    table: pd.DataFrame,
    metadata_key: bytes,
    metadata: Mapping,
    *,
    error: type[Exception] = TableFileError,
    what: str = "table",
) -> Path:
    """Write ``table`` with ``metadata`` as JSON under ``metadata_key``; same input, same bytes.

    ``error`` is the exception raised for metadata that is not plain JSON (each file
    kind has its own error class); ``what`` names the kind in messages.
    """
    path = Path(path)
    arrow = pa.Table.from_pandas(table, preserve_index=False)
    schema_metadata = dict(arrow.schema.metadata or {})
    try:
        encoded = json.dumps(dict(metadata), sort_keys=True, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError) as problem:
        raise error(f"{path}: {what} metadata is not plain JSON data ({problem})") from None
    schema_metadata[metadata_key] = encoded.encode()
    arrow = arrow.replace_schema_metadata(schema_metadata)
    with atomic_file(path) as temporary:
        pq.write_table(arrow, temporary, compression="zstd")
    return path


def read_table_file(
    path: str | os.PathLike,
    metadata_key: bytes,
    *,
    error: type[Exception] = TableFileError,
    what: str = "table",
) -> tuple[pd.DataFrame, dict]:
    """The table and its metadata; a missing, unreadable or foreign file is ``error``."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file {path} does not exist")
    try:
        arrow = pq.read_table(path)
    except (pa.ArrowException, OSError) as problem:
        raise error(f"{path}: not a readable parquet file ({problem})") from None
    raw = (arrow.schema.metadata or {}).get(metadata_key)
    if raw is None:
        raise error(f"{path}: no '{metadata_key.decode()}' metadata; not a rigmap {what} file")
    try:
        metadata = json.loads(raw)
    except json.JSONDecodeError as problem:
        raise error(f"{path}: {what} metadata is not valid JSON ({problem})") from None
    if not isinstance(metadata, dict):
        raise error(f"{path}: {what} metadata is {type(metadata).__name__}, expected an object")
    return arrow.to_pandas(), metadata
