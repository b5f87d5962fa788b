"""The ``map_mocap`` stage: the CMU clips of ``../shared/mocap/`` mapped onto a rig, and scored.

Per clip it writes the map's folder (``data/<rig>/map/<clip>/``, as ``rigmap map``
writes it) and ``metrics/<rig>/map/<clip>.json`` with what issue #14 asks to show, on
the mapped joints after scaling: joint error (cm RMS and % of the rig's height), the
largest frame-to-frame jump of any used control (training standard deviations), foot
skate on planted frames (cm per frame, source and result), keys after reduction against
frames × keyed controls, and frames per second; plus a per-frame CSV for DVC plots.
The map model it fits lives in ``data/<rig>/map/model/``, inside the stage's own
output, so the stages that read ``models/<rig>/`` do not wait for this one.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from rigmap.app.map_job import Log, MappedClip, map_from_config
from rigmap.store import Layout, atomic_file, json_ready, write_json_atomic
from rigmap.store.layout import MAP

METRICS_SET = MAP
METRICS_FORMAT = "rigmap.map_metrics/1"


def map_mocap(
    config: Mapping[str, Any], *, config_dir: str | os.PathLike, log: Log = print
) -> list[Path]:
    """Map every clip of ``map.mocap_stage`` onto ``config["rig"]``; returns the metrics files."""
    stage = config["map"]["mocap_stage"]
    layout = Layout.from_paths(config.get("paths"))
    rig_name = config["rig"]["name"]
    written = []
    for clip in stage["clips"]:
        window = {"first_frame": stage["first_frame"], "frames": stage["frames"]}
        source = Path(stage["folder"]) / f"{clip}.bvh"
        mapped = map_stage_clip(
            config, source, layout, (rig_name, MAP), window, config_dir=config_dir, log=log
        )
        written.append(write_clip_metrics(layout.map_metrics(rig_name, MAP), mapped))
    return written


def map_stage_clip(
    config: Mapping[str, Any],
    source: Path,
    layout: Layout,
    rig_stage: tuple[str, str],
    overrides: Mapping[str, Any],
    *,
    config_dir: str | os.PathLike,
    log: Log,
) -> MappedClip:
    """One clip of a map stage (``rig_stage``: rig and stage name) into
    :meth:`Layout.map_data` ``/<clip>/``, with ``overrides`` over ``map`` and the stage's map
    model cached in :meth:`Layout.map_stage_model`."""
    rig_name, stage = rig_stage
    clip_config = {
        **config,
        "map": {**config["map"], **overrides},
        "input": str(source),
        "out": str(layout.map_data(rig_name, stage)),
        "model_cache": str(layout.map_stage_model(rig_name, stage)),
    }
    (mapped,) = map_from_config(clip_config, config_dir=config_dir, log=log)
    return mapped


def clip_metrics(mapped: MappedClip) -> dict:
    """The clip's scores from its ``summary.json`` (units in the keys)."""
    s = mapped.summary
    return json_ready(
        {
            "format": METRICS_FORMAT,
            "rig": s["rig"],
            "source": s["source"],
            "frames": s["frames"],
            "fps": s["fps"],
            "mapped_joints": len(s["mapped_joints"]),
            "joint_error_rms_cm": s["joint_error_rms_cm"],
            "joint_error_max_cm": s["joint_error_max_cm"],
            "joint_error_rms_percent_of_height": s["joint_error_rms_percent_of_height"],
            "rig_height_cm": s["rig_height_cm"],
            "largest_jump_training_std": s["largest_jump_training_std"],
            "foot_skate_source_cm_per_frame": s["foot_skate_source_cm_per_frame"],
            "foot_skate_result_cm_per_frame": s["foot_skate_result_cm_per_frame"],
            "ground_penetration_source_cm": s["ground_penetration_source_cm"],
            "ground_penetration_result_cm": s["ground_penetration_result_cm"],
            "contact_slip_max_cm": s["contact_slip_max_cm"],
            "euler_flips": s["euler_flips"],
            "keys": s["keys"],
            "frames_times_keyed_controls": s["frames_times_controls"],
            "keys_per_frame_and_control": s["keys"] / max(1, s["frames_times_controls"]),
            "frames_per_second": s["frames_per_second"],
            "seconds": s["seconds"],
            "outputs": str(mapped.folder),
        }
    )


def write_clip_metrics(folder: Path, mapped: MappedClip) -> Path:
    """``<folder>/<clip>.json`` and ``<clip>.csv`` (frame, joint_error_cm, confidence)."""
    name = mapped.folder.name
    frames = pd.read_parquet(mapped.folder / "frames.parquet")
    with atomic_file(folder / f"{name}.csv", suffix=".csv") as temporary:
        frames[["frame", "joint_error_cm", "confidence"]].to_csv(temporary, index=False)
    return write_json_atomic(folder / f"{name}.json", clip_metrics(mapped))
