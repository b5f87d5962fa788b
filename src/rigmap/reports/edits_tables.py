"""The report's tables of edit propagation (Ikemoto, Arikan & Forsyth 2009; #17).

``edit_evaluate`` writes ``metrics/<subject>/edits/edits.csv`` (each edit's scores on the
held-out clips) and ``ablation.csv`` (the combined solve against its parts, §1 and §4);
each table appears when the stage ran. Every number is rigmap's own measurement: the
paper judged its results by eye.
"""

from __future__ import annotations

from pathlib import Path

from rigmap.reports.csv_tables import tables_from_csvs
from rigmap.reports.table import Table

OWN = (
    "These metrics are rigmap's own (Ikemoto et al. 2009 judged their results by eye): edit "
    "error is the mean squared error over every channel in training-std units (source: the "
    "unedited clip's), ρ the transfer ratio Σ⟨ŷ−s, g−s⟩ / Σ‖g−s‖² (1 the whole edit, 0 the "
    "source), joint errors in cm relative to the root; held out: clips never in the examples."
)
#: name → (csv, title, [(column, label, format)], note)
TABLES = {
    "table_edits": (
        "edits.csv",
        "Edit propagation: each edit on the held-out clips (§7.2)",
        [
            ("edit", "Edit", "s"),
            ("edit_error_std", "Edit error", ".3g"),
            ("source_error_std", "Source error", ".3g"),
            ("joint_rmse_cm", "Joint RMSE cm", ".2f"),
            ("source_joint_rmse_cm", "Source joint RMSE cm", ".2f"),
            ("transfer", "ρ", ".2f"),
            ("leak_cm", "Leak cm", ".2f"),
        ],
        "Leak: RMS joint move on frames the edit leaves alone (— where it leaves none).",
    ),
    "table_edits_ablation": (
        "ablation.csv",
        "Edit propagation: both predictors against either alone (§1, §4)",
        [
            ("edit", "Edit", "s"),
            ("solve", "Solve", "s"),
            ("edit_error_std", "Edit error", ".3g"),
            ("transfer", "ρ", ".2f"),
            ("jerk_ratio", "Jerk ratio", ".3f"),
            ("drift_std", "Drift", ".3g"),
        ],
        "The same GP predictions solved with Eq. 12's weights (kinematic, its regulariser, "
        "acceleration, its regulariser) set to kinematic only, acceleration only (anchored), "
        "both without regularisers, and all four.",
    ),
}


def edits_tables(metrics_root: str | Path) -> list[Table]:
    """One table per measurement over every subject the edit stages ran on (none: [])."""
    return tables_from_csvs(metrics_root, "edits", TABLES, "subject", OWN)
