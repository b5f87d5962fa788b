"""Report tables read back from the CSVs a stage writes per character.

The edit and latent stages each write ``metrics/<character>/<folder>/<name>.csv``; a table
here is every character's rows of one CSV, with the columns a spec picks and formats.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from importlib import resources
from pathlib import Path

import pandas as pd
import yaml

from rigmap.reports.catalog import rig_label
from rigmap.reports.table import MISSING, Column, Table

#: (column, label, format): format is "s" (as is), "d" (an integer) or a float format spec
ColumnSpec = tuple[str, str, str]
#: table name → (csv file name, title, column specs, note)
TableSpecs = Mapping[str, tuple[str, str, list[ColumnSpec], str]]

_SPEC_KEYS = ("csv", "title", "columns", "note")


def read_table_specs(file_name: str) -> dict[str, tuple[str, str, list[ColumnSpec], str]]:
    """The table specs in ``reports/data/<file_name>``: text and column names are data, so
    they live in a YAML file shipped with the package rather than in code."""
    path = resources.files("rigmap.reports").joinpath("data", file_name)
    loaded = yaml.safe_load(path.read_text(encoding="utf-8"))
    specs = {}
    for name, entry in (loaded or {}).items():
        if not isinstance(entry, dict) or sorted(entry) != sorted(_SPEC_KEYS):
            raise ValueError(f"{file_name}: table {name!r} must have exactly {_SPEC_KEYS}")
        columns = entry["columns"]
        if not all(isinstance(c, list) and len(c) == 3 for c in columns):
            raise ValueError(f"{file_name}: table {name!r}: a column is [column, label, format]")
        specs[name] = (entry["csv"], entry["title"], [tuple(c) for c in columns], entry["note"])
    return specs


def format_cell(value, fmt: str) -> str:
    """A display string; a missing value (None or NaN) is the report's dash."""
    if value is None or (isinstance(value, float) and pd.isna(value)):
        return MISSING
    if fmt == "s":
        return str(value)
    if fmt == "d":
        return str(int(value))
    return format(float(value), fmt)


def tables_from_csvs(
    metrics_root: str | Path,
    folder: str,
    specs: TableSpecs,
    character_column: str,
    common_note: str,
    extra_notes: Callable[[str, pd.DataFrame], list[str]] | None = None,
) -> list[Table]:
    """One table per spec whose CSV some character has (none: []); ``character_column``
    names the column that says whose rows they are, in the table's data."""
    tables = []
    for name, (csv, title, spec, note) in specs.items():
        files = sorted(Path(metrics_root).glob(f"*/{folder}/{csv}"))
        if not files:
            continue
        data = pd.concat(
            [
                pd.read_csv(path).assign(**{character_column: path.parent.parent.name})
                for path in files
            ],
            ignore_index=True,
        )
        rows = [
            [rig_label(r[character_column]), *(format_cell(r.get(c), fmt) for c, _, fmt in spec)]
            for r in data.to_dict("records")
        ]
        columns = [Column("Character", numeric=False)] + [
            Column(label, numeric=fmt != "s") for _, label, fmt in spec
        ]
        notes = [common_note, note, *(extra_notes(name, data) if extra_notes else [])]
        tables.append(Table(name, title, columns, rows, data, notes=notes))
    return tables
