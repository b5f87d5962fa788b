"""The report's tables of edit propagation (Ikemoto, Arikan & Forsyth 2009; #17).

The ``edits`` stage writes ``metrics/<subject>/edits/edits.csv`` (each edit's scores on the
held-out clips) and ``ablation.csv`` (the combined solve against its parts, §1 and §4);
each table appears when the stage ran. Every number is rigmap's own measurement: the
paper judged its results by eye.
"""

from __future__ import annotations

from pathlib import Path

from rigmap.reports.csv_tables import read_table_specs, tables_from_csvs
from rigmap.reports.table import Table

OWN = (
    "These metrics are rigmap's own (Ikemoto et al. 2009 judged their results by eye): edit "
    "error is the mean squared error over every channel in training-std units (source: the "
    "unedited clip's), ρ the transfer ratio Σ⟨ŷ−s, g−s⟩ / Σ‖g−s‖² (1 the whole edit, 0 the "
    "source), joint errors in cm relative to the root; held out: clips never in the examples."
)
#: name → (csv, title, [(column, label, format)], note), from reports/data/edits_tables.yaml
TABLES = read_table_specs("edits_tables.yaml")


def edits_tables(metrics_root: str | Path) -> list[Table]:
    """One table per measurement over every subject the edit stages ran on (none: [])."""
    return tables_from_csvs(metrics_root, "edits", TABLES, "subject", OWN)
