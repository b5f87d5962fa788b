"""The report's tables and figure of latent synthesis (Bailey, Watt & O'Brien 2016; #18).

The ``latent`` stage writes ``metrics/<rig>/latent/*.csv`` and ``summary.json`` and draws
``reports/figures/latent_<rig>.png`` (Fig 2); each table appears when the stage ran.
Every number is rigmap's own measurement: the paper reports settings, not results.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from rigmap.reports.csv_tables import read_table_specs, tables_from_csvs
from rigmap.reports.figures import FigureFile, stage_figures
from rigmap.reports.table import Table

OWN = (
    "These metrics are rigmap's own (Bailey et al. 2016 report settings): distances on mesh "
    "vertices (joints without a mesh), cm; held out: new seeded takes of each label, or a "
    "captured take's last quarter (the ARKit face), never a trained frame."
)
#: name → (csv, title, [(column, label, format)], note), from reports/data/latent_tables.yaml
TABLES = read_table_specs("latent_tables.yaml")
FIGURE_CAPTION = (
    "GPLVM latent spaces (first two dimensions), takes coloured, with and without the "
    "connectivity prior (cf. Fig 2 of Bailey et al. 2016; rigmap's fit)."
)


def latent_tables(metrics_root: str | Path) -> list[Table]:
    """One table per measurement over every rig the latent stages ran on (none: [])."""
    return tables_from_csvs(metrics_root, "latent", TABLES, "rig", OWN, _knee_notes)


def _knee_notes(name: str, data: pd.DataFrame) -> list[str]:
    return [knee_note(data)] if name == "table_latent_dims" else []


def knee_note(data: pd.DataFrame) -> str:
    """The mean mesh error per latent dimension over the swept labels and where its knee
    is (:func:`rigmap.latent.measures.knee_dimension`), said plainly."""
    means = data.groupby("latent_dim")["surface_rms_cm"].mean()
    errors = {int(q): float(e) for q, e in means.items()}
    if len(errors) < 3:
        return "Too few latent dimensions swept to look for a knee."
    # imported here: rigmap.latent loads torch, and listing rigs or reports must not
    from rigmap.latent.measures import knee_dimension

    knee = knee_dimension(errors)
    listed = ", ".join(f"{e:.3f}" for e in errors.values())
    where = "at 3, as the paper chose" if knee == 3 else f"at {knee}, not at 3"
    return (
        f"Mean over the swept labels, dimensions {min(errors)}–{max(errors)}: {listed} cm. "
        f"The knee (90 % of the drop from the first to the last dimension, ours) is {where}. "
        "Why, and how it moves with the takes' variation: docs/latent-synthesis.md and "
        "benchmarks/latent_knee.py."
    )


def latent_figures(figures_folder: str | Path) -> list[FigureFile]:
    """Fig 2 of each rig the latent stages ran on (``latent_<rig>.png``)."""
    return stage_figures(figures_folder, "latent", FIGURE_CAPTION)
