"""The report's tables and figure of latent synthesis (Bailey, Watt & O'Brien 2016; #18).

``latent_evaluate`` writes ``metrics/<rig>/latent/*.csv`` and ``summary.json`` and draws
``reports/figures/latent_<rig>.png`` (Fig 2); each table appears when the stage ran.
Every number is rigmap's own measurement: the paper reports settings, not results.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from rigmap.reports.catalog import rig_label
from rigmap.reports.csv_tables import tables_from_csvs
from rigmap.reports.figures import FigureFile
from rigmap.reports.table import Table

OWN = (
    "These metrics are rigmap's own (Bailey, Watt & O'Brien 2016 report settings, not "
    "measurements): distances on the face's mesh vertices (joints for a rig without a mesh), "
    "in cm; held-out takes are new seeded takes of each label, never a training take."
)
#: name → (csv, title, [(column, label, format)], note)
TABLES = {
    "table_latent_models": (
        "pca.csv",
        "Latent synthesis: PCA dimensions at 85 % of the variance per model (§4.2)",
        [
            ("model", "Model", "s"),
            ("scaled_at_0.85", "Scaled controls", "d"),
            ("unscaled_at_0.85", "Unscaled controls", "d"),
            ("model_pca_dims", "Model's PCA", "d"),
        ],
        "The model's PCA size is latent.n_pca (ours, 8 on the face): at 85 % one model "
        "cannot reproduce another's poses.",
    ),
    "table_latent_scaling": (
        "scaling.csv",
        "Latent synthesis: scaled against unscaled controls, held-out error of PCA alone (§4.2)",
        [
            ("pca_dims", "PCA dims", "d"),
            ("scaled_controls_rms", "Scaled · controls RMS", ".4f"),
            ("unscaled_controls_rms", "Unscaled · controls RMS", ".4f"),
            ("scaled_surface_rms_cm", "Scaled · mesh cm", ".4f"),
            ("unscaled_surface_rms_cm", "Unscaled · mesh cm", ".4f"),
        ],
        "The paper: scaled is worse in control space and better on the mesh.",
    ),
    "table_latent_dims": (
        "latent_dims.csv",
        "Latent synthesis: held-out reconstruction against the latent dimension (§6)",
        [
            ("label", "Label", "s"),
            ("latent_dim", "Latent dim", "d"),
            ("surface_rms_cm", "Mesh RMS cm", ".4f"),
            ("controls_rms", "Controls RMS", ".4f"),
            ("fit_s", "Fit s", ".1f"),
        ],
        "Held-out takes projected into the model (Eq 15) and mapped back (Eq 8). The paper "
        "chose 3 dimensions as the smallest that looked as good as more (§6, perceptual); "
        "the numbers here are as measured, and the knee below is computed from them.",
    ),
    "table_latent_one_vs_per_label": (
        "one_vs_per_label.csv",
        "Latent synthesis: one model for all labels against one per label (§5.2, §7)",
        [
            ("models", "Models", "s"),
            ("latent_dim", "Latent dim", "d"),
            ("surface_rms_cm", "Mesh RMS cm", ".4f"),
            ("controls_rms", "Controls RMS", ".4f"),
            ("fit_s", "Fit s", ".1f"),
        ],
        "Held-out takes of the labels compared, projected into their model(s).",
    ),
    "table_latent_matching": (
        "matching.csv",
        "Latent synthesis: matching points per model pair (§5.2; the paper: 10–50)",
        [
            ("pair", "Pair", "s"),
            ("points", "Points", "d"),
            ("candidates", "Tried", "d"),
            ("spread_latent", "Spread (latent)", ".3f"),
            ("distance_cm_median", "Distance median cm", ".4f"),
        ],
        "A pair is kept when the two poses' largest vertex distance is under the threshold "
        "(latent.match_threshold_cm, ours).",
    ),
    "table_latent_smoothness": (
        "smoothness.csv",
        "Latent synthesis: transition smoothness against a motion graph (Kovar et al. 2002)",
        [
            ("pair", "Pair", "s"),
            ("ours_peak_acc_rel_p95", "Ours · peak accel", ".3f"),
            ("graph_peak_acc_rel_p95", "Graph · peak accel", ".3f"),
            ("ours_peak_jerk_rel_p95", "Ours · peak jerk", ".3f"),
            ("graph_peak_jerk_rel_p95", "Graph · peak jerk", ".3f"),
            ("ours_start_fraction", "Ours · start frames", ".2f"),
            ("graph_start_fraction", "Graph · start frames", ".2f"),
        ],
        "Peak vertex acceleration and jerk around the switch over the training takes' 95th "
        "percentile; start frames: the fraction of source frames a transition can start from "
        "(the graph's: a transition under 0.2 cm RMS over its 12-frame window, ours).",
    ),
    "table_latent_suites": (
        "suites.csv",
        "Latent synthesis: scripted command suites (§5.3)",
        [
            ("command", "Command", "s"),
            ("count", "Commands", "d"),
            ("success_rate", "Success", ".2f"),
            ("frames_median", "Frames median", ".0f"),
            ("frames_max", "Frames max", "d"),
        ],
        "Seeded MOVE (line and graph paths), IDLE, TRANSITION and PLAY commands.",
    ),
}


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
    return [
        FigureFile(
            path,
            f"{rig_label(path.stem.removeprefix('latent_'))}: GPLVM latent spaces (first two "
            "dimensions), takes coloured, with and without the connectivity prior (cf. Fig 2 "
            "of Bailey et al. 2016; rigmap's fit).",
        )
        for path in sorted(Path(figures_folder).glob("latent_*.png"))
    ]
