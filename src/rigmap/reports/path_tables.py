"""The report's table and figure of Fig. 7: a walk bent along a path over terrain, mapped.

The ``map_path`` stage writes ``metrics/<rig>/map_path/<name>.json`` and
``reports/figures/map_path_<rig>.png``; both appear when the stage ran (none: nothing).
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from rigmap.reports.catalog import rig_label
from rigmap.reports.figures import FigureFile, stage_figures
from rigmap.reports.table import MISSING, Column, Table

PREFIX = "map_path"  # rigmap.app.map_path.MAP_PATH: the stage's metrics set and figure prefix
ROWS = {  # the stage's score rows, in the order the edit makes them
    "bent_only": "bent only (flat, feet free)",
    "edited": "edited: feet held, on the terrain",
    "mapped": "the rig, mapped",
}
TITLE = "Fig. 7: a walk bent along a path over terrain, before and after mapping"
COLUMNS = [  # (label, numeric)
    ("Character", False),
    ("Run", False),
    ("Motion", False),
    ("Foot skate (cm/frame)", True),
    ("Penetration, deepest / mean (cm)", False),
    ("Joint RMS vs edit (cm)", True),
]
CAPTION = (
    "the walk bent along the path over the terrain (top view with the planted feet; side "
    "view of the feet over the terrain), the edited joints (solid) and the mapped rig "
    "(dashed) (cf. Fig. 7)."
)
NOTE = (
    "Paper Fig. 7 (rigmap's own numbers; the paper reports none): a corpus walk looped by its "
    "own cycle, bent along the path, planted feet held and set on the terrain, then mapped "
    "onto the rig by `rigmap map`. Skate: cm per frame a planted foot joint slides (plants "
    "found on the straight walk); penetration: cm below the foot joint's standing height "
    "over the terrain (deepest, and mean over frames); joint error: the rig against the "
    "edited joints, cm RMS on the mapped joints."
)


def path_table(metrics_root: str | Path) -> Table | None:
    """One row per rig, run and stage of the edit, or None when ``map_path`` did not run."""
    files = sorted(Path(metrics_root).glob(f"*/{PREFIX}/*.json"))
    records = [(path.stem, json.loads(path.read_text())) for path in files]
    rows, data = [], []
    for name, record in records:
        for key, label in ROWS.items():
            score = record["scores"].get(key)
            if score is None:
                continue
            error = score.get("joint_error_rms_cm")
            rows.append(
                [
                    rig_label(record["rig"]),
                    f"{name} ({record['terrain']}, {record['frames']} frames)",
                    label,
                    f"{score['foot_skate_cm_per_frame']:.2f}",
                    f"{score['penetration_max_cm']:.2f} / {score['penetration_mean_cm']:.2f}",
                    MISSING if error is None else f"{error:.2f}",
                ]
            )
            data.append({"rig": record["rig"], "run": name, "row": key, **score})
    if not rows:
        return None
    columns = [Column(label, numeric=numeric) for label, numeric in COLUMNS]
    frame = pd.DataFrame.from_records(data)
    return Table("table_map_path", TITLE, columns, rows, frame, [NOTE])


def path_figures(figures_folder: str | Path) -> list[FigureFile]:
    """The stage's figure of each rig it ran on (``map_path_<rig>.png``)."""
    return stage_figures(figures_folder, PREFIX, CAPTION)
