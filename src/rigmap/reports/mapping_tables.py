"""The report's tables of the mapping stages: real mocap onto rigs, and partial input (§6.3).

``map_mocap`` writes ``metrics/<rig>/map/<clip>.json`` and ``map_partial`` writes
``metrics/<rig>/map_partial/partial_inputs.csv``; a table appears when its stage ran.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from rigmap.reports.catalog import rig_label
from rigmap.reports.table import MISSING, Column, Table

MOCAP_NOTE = (
    "Real CMU mocap (../shared/mocap/) mapped onto each rig by `rigmap map`: joint error on "
    "the mapped joints after scaling, the largest frame-to-frame jump of any used control in "
    "training standard deviations, foot skate on planted frames of the result and of the "
    "source, keys after reduction against frames × keyed controls, frames per second of the "
    "whole mapping. The data used in this project was obtained from mocap.cs.cmu.edu. The "
    "database was created with funding from NSF EIA-0196217."
)
PARTIAL_NOTE = (
    "A mapping trained on a joint subset beside the mapping from every joint (full), on the "
    "test clips: error on the joints given and on the whole body (every joint, against the "
    "animator's pose), before and after refinement (refined on the frames the stage "
    "refines); 'Whole body, full input' is the full mapping's on the same frames."
)
#: the paper's figure of each subset the map_partial stage names (conf/map_partial)
SUBSET_FIGURES = {
    "feet": "feet only (Fig. 6)",
    "effectors": "seven effectors (Fig. 5)",
    "landmarks": "FaceIK landmarks (Fig. 10)",
}
FULL_INPUT = "full"  # rigmap.map.partial_evaluation.FULL_INPUT: the row of every joint


def mocap_table(metrics_root: str | Path) -> Table | None:
    """One row per rig and clip of the ``map_mocap`` stage, or None when it did not run."""
    files = sorted(Path(metrics_root).glob("*/map/*.json"))
    records = [json.loads(path.read_text()) for path in files]
    if not records:
        return None
    rows = [
        [
            rig_label(r["rig"]),
            Path(r["source"]).stem,
            str(r["frames"]),
            f"{r['joint_error_rms_cm']:.2f} ({r['joint_error_rms_percent_of_height']:.2f} %)",
            f"{r['largest_jump_training_std']:.2f}",
            _pair(r["foot_skate_result_cm_per_frame"], r["foot_skate_source_cm_per_frame"]),
            f"{r['keys']} / {r['frames_times_keyed_controls']}",
            f"{r['frames_per_second']:.2f}",
        ]
        for r in records
    ]
    columns = [
        Column("Character", numeric=False),
        Column("Clip", numeric=False),
        Column("Frames"),
        Column("Joint RMS, cm (% of height)", numeric=False),
        Column("Largest control jump (std)"),
        Column("Foot skate, result / source (cm/frame)", numeric=False),
        Column("Keys / frames × controls", numeric=False),
        Column("Frames/s"),
    ]
    data = pd.DataFrame.from_records(
        [{k: v for k, v in r.items() if not isinstance(v, dict | list)} for r in records]
    )
    return Table(
        name="table_map_mocap",
        title="Mocap onto the rigs: the CMU walks mapped by rigmap map",
        columns=columns,
        rows=rows,
        data=data,
        notes=[MOCAP_NOTE],
    )


def partial_table(metrics_root: str | Path) -> Table | None:
    """Given-joint and whole-body errors per subset and stage of ``map_partial``, beside the
    full input's whole-body error; or None when the stage did not run."""
    files = sorted(Path(metrics_root).glob("*/map_partial/partial_inputs.csv"))
    if not files:
        return None
    data = pd.concat([pd.read_csv(path) for path in files], ignore_index=True)
    full = data[data.subset == FULL_INPUT].set_index(["rig", "stage"])["body_error_cm"]
    data["full_input_body_error_cm"] = [full.get((r.rig, r.stage)) for r in data.itertuples()]
    rows = [
        [
            rig_label(r.rig),
            f"{r.subset} ({r.given_joints} joints)",
            r.stage,
            str(r.frames),
            f"{r.given_error_cm:.2f}",
            f"{r.body_error_cm:.2f}",
            MISSING if pd.isna(r.full_input_body_error_cm) else f"{r.full_input_body_error_cm:.2f}",
            f"{r.ground_truth_error:.2f}",
        ]
        for r in data.itertuples()
    ]
    columns = [
        Column("Character", numeric=False),
        Column("Input", numeric=False),
        Column("Stage", numeric=False),
        Column("Frames"),
        Column("Given joints (cm RMS)", "Joint Error", short_group="joint"),
        Column("Whole body (cm RMS)", "Joint Error", short_group="joint"),
        Column("Whole body, full input (cm RMS)", "Joint Error", short_group="joint"),
        Column("Ground Truth Error"),
    ]
    return Table(
        name="table_map_partial",
        title=_partial_title(data),
        columns=columns,
        rows=rows,
        data=data,
        notes=[PARTIAL_NOTE, *_whole_input_notes(data)],
    )


def _partial_title(data: pd.DataFrame) -> str:
    """The table's title from the subsets it holds, in their order."""
    subsets = [s for s in dict.fromkeys(data.subset) if s != FULL_INPUT]
    named = [SUBSET_FIGURES.get(s, s) for s in subsets]
    listed = named[0] if len(named) == 1 else ", ".join(named[:-1]) + " and " + named[-1]
    return f"Partial input: {listed} beside the full joints"


def _whole_input_notes(data: pd.DataFrame) -> list[str]:
    """A note per rig whose subset is every joint it has (the face's landmarks): its rows
    and the full input's are then the same mapping."""
    notes = []
    for rig, rows in data.groupby("rig", sort=False):
        every = rows.loc[rows.subset == FULL_INPUT, "given_joints"]
        covering = rows.loc[
            (rows.subset != FULL_INPUT) & rows.given_joints.isin(every), "subset"
        ].unique()
        for subset in covering:
            notes.append(
                f"{rig_label(rig)}: its {subset} are all {int(every.iloc[0])} of its joints, "
                "so their rows are the full input's: the given joints are the whole body."
            )
    return notes


def _pair(result: float, source: float) -> str:
    return f"{result:.2f} / {source:.2f}"
