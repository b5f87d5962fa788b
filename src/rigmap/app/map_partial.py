"""The ``map_partial`` stage's work: partial input and motion editing on a rig's test clips.

Reads the rig's train corpus and poses and its test clips (:class:`rigmap.store.Layout`),
fits one subset mapping per input (every joint, then the rig's subsets: the feet and the
effectors of a body, the face's landmarks for FaceIK), scores them
(:mod:`rigmap.map.partial_evaluation`), maps the motion-editing demo back with the full
mapping (:mod:`rigmap.map.motion_edit`) when the rig has one, and writes into
``metrics/<rig>/map_partial/``:

- ``partial_inputs.json``: one row per (input, guess/refined) plus the settings;
- ``partial_inputs.csv``: the same rows as a table the report includes;
- ``motion_edit.json``: how closely the rig follows the edited feet and hand (a rig with
  ``map_partial.edit_joints``; the face has no locomotion to edit, so no demo).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rigmap.errors import RigmapError
from rigmap.map.clip import MapSettings
from rigmap.map.motion_edit import MotionEdit, map_edit
from rigmap.map.partial import JointSubset
from rigmap.map.partial_evaluation import (
    FULL_INPUT,
    PartialInputSettings,
    evaluate_partial_inputs,
    fit_subset_mappings,
    training_data,
)
from rigmap.store import Layout, atomic_file, json_ready, write_json_atomic
from rigmap.store.layout import MAP_PARTIAL

METRIC_SET = MAP_PARTIAL
EDIT_REFINE_ITERATIONS = 3  # refinement of the edited clip (ours)


def read_training(rig, layout: Layout):
    """The rig's train split as the subset mappings learn from it, and its poses table."""
    from rigmap.animation.corpus_files import read_corpus_split
    from rigmap.animation.posing import PoseTable

    poses = PoseTable.read(
        layout.poses(rig.name, "train"), rig=rig.name, n_joints=rig.n_joints, split="train"
    )
    corpus = read_corpus_split(rig, layout, "train")
    Y = corpus.table[rig.used_controls].to_numpy(dtype=np.float64)
    return training_data(rig, poses, Y), poses


def clip_world(poses, clip: str, frames: int) -> np.ndarray:
    """World joints ``(F, J, 3)`` of the first ``frames`` frames of ``clip`` in a poses table."""
    rows = np.flatnonzero(poses.table["clip"].to_numpy() == clip)
    if rows.size == 0:
        raise MapPartialConfigError(
            f"edit clip {clip!r} is not a train clip; the train clips are {poses.clip_names}"
        )
    rows = rows[:frames]
    return poses.positions()[rows] + poses.cog()[rows][:, None, :]


def map_partial(
    rig,
    layout: Layout,
    subsets: Mapping[str, JointSubset],
    make_regressor: Callable[[], object],
    settings: PartialInputSettings,
    edit: MotionEdit | None,
    *,
    edit_clip: str,
    edit_frames: int,
) -> list[Path]:
    """Evaluate ``subsets`` on ``rig``'s test clips; edit the first ``edit_frames`` frames of
    the train clip ``edit_clip`` (Fig. 7 edits locomotion made from animator data) and map
    it back with the full mapping (``edit`` None: no demo, no ``motion_edit.json``).
    Returns the files written."""
    from rigmap.evaluation.methods import TestSet

    started = time.perf_counter()
    training, poses = read_training(rig, layout)
    world = None if edit is None else clip_world(poses, edit_clip, edit_frames)
    test_set = TestSet.load(rig, layout)
    fitted = fit_subset_mappings(rig, subsets, training, make_regressor)
    rows = evaluate_partial_inputs(rig, fitted, training, test_set, settings)
    folder = layout.map_partial_metrics(rig.name)
    table = pd.DataFrame([r.to_dict() for r in rows])
    meta = {
        "rig": rig.name,
        "test_clips": [c.name for c in test_set.clips],
        "test_frames": test_set.frames,
        "settings": asdict(settings),
        "subsets": {n: m.subset.to_dict() for n, (m, _) in fitted.items()},
        "units": "errors in cm RMS over frames and joints (world); ground truth in "
        "training std squared (§6.1)",
        "seconds": time.perf_counter() - started,
    }
    written = [
        write_json_atomic(
            folder / "partial_inputs.json", json_ready({**meta, "rows": table.to_dict("records")})
        ),
        _write_csv(folder / "partial_inputs.csv", table),
    ]
    if edit is not None:
        record = _edit_record(rig, fitted[FULL_INPUT][0], world, edit, training, settings)
        written.append(
            write_json_atomic(
                folder / "motion_edit.json", json_ready({**record, "clip": edit_clip})
            )
        )
    return written


def _edit_record(rig, mapping, world, edit: MotionEdit, training, settings) -> dict:
    """The motion-editing demo mapped back with the full ``mapping``: its record."""
    edit_settings = MapSettings(
        refine_iterations=EDIT_REFINE_ITERATIONS, prior_weight=settings.prior_weight
    )
    edited = map_edit(
        rig,
        mapping,
        world,
        edit,
        edit_settings,
        control_std=training.std,
        hold_values=training.median,
    )
    return {
        "rig": rig.name,
        **edited.to_dict(),
        "edit": asdict(edit),
        "refine_iterations": EDIT_REFINE_ITERATIONS,
    }


def _write_csv(path: Path, table: pd.DataFrame) -> Path:
    with atomic_file(path) as temp:
        table.to_csv(temp, index=False, float_format="%.6g")
    return path


class MapPartialConfigError(RigmapError, ValueError):
    """A ``map_partial`` config that names subsets or edit joints the rig does not have."""


def map_partial_from_config(config: Mapping[str, Any]) -> list[Path]:
    """The stage from a composed config (a plain mapping: ``rig``, ``regressor``, ``paths``,
    ``map_partial``)."""
    from rigmap.app.objects import instantiate_as
    from rigmap.regression.base import Regressor
    from rigmap.rigs import load

    options = dict(config["map_partial"])
    rig_options = {k: v for k, v in dict(config["rig"]).items() if k != "corpus"}
    with load(rig_options) as rig:
        subsets = _subsets(rig, options)
        joints = (options.get("edit_joints") or {}).get(rig.name)
        edit_options = dict(options["edit"])
        edit_frames = int(edit_options.pop("frames"))
        edit_clip = str(edit_options.pop("clip"))
        edit_options = {k: tuple(v) if isinstance(v, list) else v for k, v in edit_options.items()}
        edit = None  # no edit_joints entry (the face): no motion-editing demo
        if joints is not None:
            edit = MotionEdit(tuple(joints["feet"]), joints["hand"], **edit_options)
        settings = PartialInputSettings(
            int(options["refine_iterations"]),
            int(options["refine_every"]),
            float(options["prior_weight"]),
        )

        def make_regressor():
            return instantiate_as(
                config["regressor"], Regressor, "regressor", MapPartialConfigError
            )

        layout = Layout.from_paths(config["paths"])
        return map_partial(
            rig,
            layout,
            subsets,
            make_regressor,
            settings,
            edit,
            edit_clip=edit_clip,
            edit_frames=edit_frames,
        )


def _subsets(rig, options: Mapping[str, Any]) -> dict[str, JointSubset]:
    """The subsets ``input_joints`` names (None: every one of the rig's, in order), from
    ``subsets.<rig>``, checked against the rig."""
    table = (options.get("subsets") or {}).get(rig.name)
    if not table:
        raise MapPartialConfigError(f"map_partial.subsets has no entry for rig {rig.name!r}")
    chosen = options.get("input_joints")
    names = list(table) if chosen is None else list(chosen)
    unknown = [n for n in names if n not in table]
    if unknown or not names:
        raise MapPartialConfigError(
            f"map_partial.input_joints {names}: {unknown or 'none given'}; rig {rig.name!r} "
            f"has subsets {sorted(table)}"
        )
    return {n: JointSubset.from_mapping(table[n], name=n, rig=rig) for n in names}
