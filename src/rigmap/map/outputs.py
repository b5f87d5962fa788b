"""What ``rigmap map`` writes for one clip, in one folder, atomically.

- ``controls.parquet``: ``frame`` and every control of the rig (unused ones at their
  defaults), the values of the reduced keys on every frame;
- ``frames.parquet``: per frame, the RMS joint error over the mapped joints (cm), the
  mapping's confidence (:mod:`rigmap.map.confidence`, when given) and, when feet were
  given, whether each foot was planted;
- ``targets.parquet``: ``frame`` and ``<joint>.x``, ``.y``, ``.z`` of each mapped joint: the
  retargeted source the map was given (world cm, after planted feet were pinned), what
  ``joint_error_cm`` is measured against; the studio's Review view draws it beside the rig;
- ``keys.json``: per used control, its keys (frame, value, Bézier handles): the sparse
  curves an animator edits;
- ``result.bvh``: the rig's joints at the mapped controls (world cm, Y up);
- ``summary.json``: the numbers a user checks first (errors, skate, jumps, key counts,
  seconds, frames per second).
The folder appears whole or not at all (:func:`rigmap.store.write_folder_atomic`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.map.bvh_export import write_joint_bvh
from rigmap.map.clip import MapResult
from rigmap.store import json_ready, write_folder_atomic, write_json_atomic

SUMMARY_FORMAT = "rigmap.map_summary/1"


@dataclass(frozen=True)
class MappedClip:
    """One clip's output folder and its headline numbers (``summary.json``, as written)."""

    folder: Path
    summary: dict


def summary(result: MapResult, rig) -> dict:
    """The clip's headline numbers (units in the keys)."""
    error = result.frame_error_cm
    height = rig.rest_height()
    total = sum(v for k, v in result.seconds.items() if k.endswith("_s"))
    return json_ready(
        {
            "format": SUMMARY_FORMAT,
            "rig": result.rig,
            "source": result.source,
            "frames": result.n_frames,
            "fps": result.fps,
            "mapped_joints": list(result.joint_names),
            "joint_error_rms_cm": float(np.sqrt((error**2).mean())),
            "joint_error_max_cm": float(error.max()),
            "joint_error_rms_percent_of_height": float(100 * np.sqrt((error**2).mean()) / height),
            "rig_height_cm": height,
            "foot_skate_source_cm_per_frame": result.skate_source_cm,
            "foot_skate_result_cm_per_frame": result.skate_result_cm,
            "ground_penetration_source_cm": result.penetration_source_cm,
            "ground_penetration_result_cm": result.penetration_result_cm,
            "contact_slip_max_cm": result.contact_slip_cm,
            "euler_flips": result.flips,
            "largest_jump_training_std": result.largest_jump_std,
            "keys": result.keys.key_count,
            "keyed_controls": len(result.keys.curves),
            "frames_times_controls": result.n_frames * len(result.keys.curves),
            "key_tolerance_max_joint_error_cm": result.keys.max_joint_error_cm,
            "seconds": result.seconds,
            "frames_per_second": result.n_frames / total if total > 0 else None,
        }
    )


def write_map_outputs(
    folder: str | os.PathLike,
    result: MapResult,
    rig,
    *,
    confidence: np.ndarray | None = None,
    extra: Callable[[Path], None] | None = None,
) -> MappedClip:
    """Write the clip's folder (see the module docstring); returns its path and its summary
    (the numbers of ``summary.json``, so no caller reads back what was just written).

    ``confidence`` (per frame) becomes a column of ``frames.parquet``; ``extra(staging)``
    writes more files (previews, a ``.blend``) into the folder before it appears.
    """

    def fill(staging: Path) -> None:
        frames = np.arange(result.n_frames)
        controls = pd.DataFrame(result.controls, columns=rig.control_names)
        controls.insert(0, "frame", frames)
        controls.to_parquet(staging / "controls.parquet", index=False)
        per_frame = pd.DataFrame({"frame": frames, "joint_error_cm": result.frame_error_cm})
        if confidence is not None:
            per_frame["confidence"] = np.asarray(confidence, dtype=np.float64)
        if result.contacts is not None:
            for k, foot in enumerate(result.contacts.feet):
                per_frame[f"planted.{foot}"] = result.contacts.planted[:, k]
        per_frame.to_parquet(staging / "frames.parquet", index=False)
        _targets_table(result).to_parquet(staging / "targets.parquet", index=False)
        write_json_atomic(staging / "keys.json", _keys(result))
        pose = rig.pose(result.controls)
        world = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
        rest_pose = rig.pose(rig.controls.defaults[None])
        rest = (np.asarray(rest_pose.positions) + np.asarray(rest_pose.cog)[:, None, :])[0]
        write_joint_bvh(
            staging / "result.bvh", rig.joint_names, rig.parents, world, rest, result.fps
        )
        write_json_atomic(staging / "summary.json", headline)
        if extra is not None:
            extra(staging)

    headline = summary(result, rig)
    return MappedClip(write_folder_atomic(folder, fill), headline)


def _targets_table(result: MapResult) -> pd.DataFrame:
    columns = [f"{joint}.{axis}" for joint in result.joint_names for axis in "xyz"]
    flat = np.asarray(result.targets, dtype=np.float64).reshape(result.n_frames, len(columns))
    table = pd.DataFrame(flat, columns=columns)
    table.insert(0, "frame", np.arange(result.n_frames))
    return table


def _keys(result: MapResult) -> dict:
    curves = {}
    for name, curve in zip(result.keys.control_names, result.keys.curves, strict=True):
        curves[name] = [
            {"frame": float(f), "value": float(v), "in_handle": list(i), "out_handle": list(o)}
            for f, v, i, o in zip(
                curve.frames, curve.values, curve.in_handles, curve.out_handles, strict=True
            )
        ]
    return json_ready({"fps": result.fps, "frames": result.n_frames, "curves": curves})
