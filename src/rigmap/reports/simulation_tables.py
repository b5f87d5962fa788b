"""The report's table and figure of Fig. 9: a soft-body simulation mapped onto the squirrel.

The ``simulate`` stage writes ``metrics/<rig>/simulate/summary.json`` and
``reports/figures/simulate_<rig>.png``; both appear when the stage ran (none: nothing, so a
test tree without the stage builds its report as before).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from rigmap.reports.catalog import rig_label
from rigmap.reports.figures import FigureFile, stage_figures
from rigmap.reports.table import Column, Table

PREFIX = "simulate"  # rigmap.app.simulate.SIMULATE: the stage's metrics set and figure prefix
TITLE = "Fig. 9: a soft-body simulation (Blender) mapped onto the squirrel rig"
COLUMNS = [  # (label, numeric)
    ("Character", False),
    ("Frames", True),
    ("Vertices read", True),
    ("Vertex error RMS (cm)", True),
    ("% of height", True),
    ("Median / max frame (cm)", False),
    ("Guess only, RMS (cm)", True),
    ("ms per frame", True),
    ("Teeth vertices in body: simulation / rig", False),
]
NOTE = (
    "Paper Fig. 9 (rigmap's own numbers; the paper reports none): the squirrel's rest mesh "
    "dropped, squashed and pushed as a soft body by Blender's cloth solver (pressure, parts "
    "tied by springs, feet pinned), its vertices mapped by a GPR on a vertex subset and "
    "refined. Vertex error: the rig's whole mesh at the mapped controls against the simulated "
    "mesh, RMS over every vertex and frame; teeth: teeth vertices inside the body's closed "
    "surface (winding number), summed over frames. docs/simulation.md."
)
CAPTION = (
    "the simulated soft body (top) and the rig at the mapped controls (bottom), side view, "
    "with the per-frame vertex error (cf. Fig. 9)."
)


def simulation_table(metrics_root: str | Path) -> Table | None:
    """One row per rig the stage ran on, or None when ``simulate`` did not run."""
    files = sorted(Path(metrics_root).glob(f"*/{PREFIX}/summary.json"))
    records = [json.loads(path.read_text()) for path in files]
    if not records:
        return None
    rows = []
    for r in records:
        teeth = r["teeth_inside_body"]
        rows.append(
            [
                rig_label(r["rig"]),
                str(r["frames"]),
                str(r["subset"]["vertices"]),
                f"{r['vertex_error_rms_cm']:.2f}",
                f"{r['vertex_error_rms_percent_of_height']:.1f}",
                f"{r.get('vertex_error_median_cm', float('nan')):.2f} / "
                f"{r['vertex_error_max_cm']:.2f}",
                f"{r['guess_vertex_error_rms_cm']:.2f}",
                f"{1000 * r['seconds_per_frame']:.0f}",
                f"{teeth['simulation']['teeth_vertex_frames_inside']} / "
                f"{teeth['rig']['teeth_vertex_frames_inside']}",
            ]
        )
    columns = [Column(label, numeric=numeric) for label, numeric in COLUMNS]
    frame = pd.json_normalize(records)
    return Table("table_simulate", TITLE, columns, rows, frame, [NOTE])


def simulation_figures(figures_folder: str | Path) -> list[FigureFile]:
    """The stage's figure of each rig it ran on (``simulate_<rig>.png``)."""
    return stage_figures(figures_folder, PREFIX, CAPTION)
