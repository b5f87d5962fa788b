"""Where the experiment's files live and how they are written (one door for paths and I/O).

- :class:`Layout` knows every path of a run (``data/<rig>/{corpus,poses,samples}``,
  ``models/<rig>/<model id>``, ``metrics/<rig>/<set>/``, ``reports/``);
- :class:`ModelId` names a fitted mapping (``<regressor>-<sampler>-<kernel>``);
- :mod:`rigmap.store.atomic` writes files and folders so a killed writer leaves nothing
  half-written;
- :mod:`rigmap.store.table_file` reads and writes parquet tables with JSON metadata;
- :func:`json_ready` turns numpy values into plain JSON;
- :func:`read_data_file` reads a hand-written JSON or YAML file with errors naming it.
"""

from rigmap.store.atomic import (
    OutputConflictError,
    atomic_file,
    write_bytes_atomic,
    write_folder_atomic,
    write_json_atomic,
    write_text_atomic,
)
from rigmap.store.data_file import read_data_file
from rigmap.store.json_ready import json_ready
from rigmap.store.layout import USER_OUTPUTS, Layout, ModelId
from rigmap.store.table_file import TableFileError, read_table_file, write_table_file

__all__ = [
    "USER_OUTPUTS",
    "Layout",
    "ModelId",
    "OutputConflictError",
    "TableFileError",
    "atomic_file",
    "json_ready",
    "read_data_file",
    "read_table_file",
    "write_bytes_atomic",
    "write_folder_atomic",
    "write_json_atomic",
    "write_table_file",
    "write_text_atomic",
]
