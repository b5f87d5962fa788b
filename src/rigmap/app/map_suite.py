"""The real-mocap suite: every clip of ``../shared/mocap/``, whole, mapped onto a rig, scored.

Issue #37's bar is set on real motion of every kind the folder holds (walks at several
speeds, runs, jumps, uneven ground, sitting and climbing, a dance), not on 16 frames of
two walks. Each clip is mapped whole at ``map.fps`` as ``rigmap map`` maps it (its
skeleton matched when it is the other CMU conversion, a T-pose frame cut, glitch frames
rebuilt) into ``<data>/<rig>/map_suite/<clip>/``; per clip
``<metrics>/<rig>/map_suite/<clip>.json`` holds the :mod:`rigmap.app.map_stage`
scores plus the motion kind, and ``<reports>/map_suite/<rig>.md`` is the page: one
row per clip with joint RMS (cm, % height), skate against the source's, ground
penetration, the largest control jump (training std), keys per frame and control, Euler
flips and frames per second, then the bars of the issue, met or not.

It maps about 4 000 frames (30 fps), 5-6 min on the shared 2 cores: too long for the
quick replication, so it is ``make mocap-suite``, not a DVC stage of ``rigmap reproduce``.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rigmap.app.map_job import Log
from rigmap.app.map_stage import clip_metrics, map_stage_clip
from rigmap.store import Layout, write_json_atomic, write_text_atomic
from rigmap.store.layout import MAP_SUITE

METRICS_SET = MAP_SUITE
BARS = {  # issue #37's bars on the biped (walks: joint RMS at most 1 cm)
    "joint_error_rms_cm": 1.5,
    "largest_jump_training_std": 5.0,
    "keys_per_frame_and_control": 0.15,
}


class SuiteError(ValueError):
    """A suite config naming no clips, or a folder without them."""


def suite_clips(options: Mapping) -> list[Path]:
    """The ``*.bvh`` files of ``map.mocap_suite.folder`` (all of them, or its ``clips``)."""
    folder = Path(options["folder"])
    names = options.get("clips")
    files = sorted(folder.glob("*.bvh")) if not names else [folder / f"{n}.bvh" for n in names]
    missing = [str(f) for f in files if not f.is_file()]
    if not files or missing:
        raise SuiteError(f"map.mocap_suite: no clips to map in {folder} (missing: {missing})")
    return files


def map_suite(
    config: Mapping[str, Any], *, config_dir: str | os.PathLike, log: Log = print
) -> Path:
    """Map every suite clip whole onto ``config["rig"]``; returns the report page."""
    options = config["map"]["mocap_suite"]
    layout = Layout.from_paths(config.get("paths"))
    rig_name = config["rig"]["name"]
    kinds = dict(options.get("kinds") or {})
    rows = []
    for source in suite_clips(options):
        whole = {"first_frame": 0, "frames": None, "preview": False}
        mapped = map_stage_clip(
            config, source, layout, (rig_name, MAP_SUITE), whole, config_dir=config_dir, log=log
        )
        row = {**clip_metrics(mapped), "clip": source.stem, "kind": kinds.get(source.stem, "")}
        row["euler_flips"] = mapped.summary["euler_flips"]
        folder = layout.map_metrics(rig_name, MAP_SUITE)
        write_json_atomic(folder / f"{source.stem}.json", row)
        rows.append(row)
    # beside the report, not in reports/tables/ (the report stage owns that folder whole)
    page = layout.map_suite_page(rig_name)
    return write_text_atomic(page, suite_page(rig_name, rows))


def suite_page(rig_name: str, rows: list[dict]) -> str:
    """The suite's markdown page: a row per clip, then the bars met."""
    lines = [
        f"# Real-mocap suite onto `{rig_name}` (issue #37)",
        "",
        "Every clip of `../shared/mocap/` mapped whole (`make mocap-suite`). Skate: planted "
        "heels and toes, cm per frame, result / source; penetration: deepest below a joint's "
        "planted height, cm, result / source.",
        "",
        "| clip | kind | frames | RMS cm | % height | skate | penetration | jump std | "
        "keys/frame·control | flips | frames/s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['clip']} | {r['kind']} | {r['frames']} | {r['joint_error_rms_cm']:.2f} | "
            f"{r['joint_error_rms_percent_of_height']:.2f} | "
            f"{r['foot_skate_result_cm_per_frame']:.3f} / {r['foot_skate_source_cm_per_frame']:.3f}"
            f" | {r['ground_penetration_result_cm']:.1f} / {r['ground_penetration_source_cm']:.1f}"
            f" | {r['largest_jump_training_std']:.1f} | {r['keys_per_frame_and_control']:.3f} | "
            f"{r['euler_flips']} | {r['frames_per_second']:.1f} |"
        )
    lines += ["", "Bars (issue #37, biped):", ""]
    lines += [_bar(name, limit, rows) for name, limit in BARS.items()]
    skate = sum(
        r["foot_skate_result_cm_per_frame"] <= r["foot_skate_source_cm_per_frame"] for r in rows
    )
    flips = sum(r["euler_flips"] == 0 for r in rows)
    lines += [
        f"- skate no more than the source's: {skate} of {len(rows)} clips",
        f"- no Euler flip: {flips} of {len(rows)} clips",
        "",
    ]
    lines += [
        "The data used in this project was obtained from mocap.cs.cmu.edu. The database "
        "was created with funding from NSF EIA-0196217.",
        "",
    ]
    return "\n".join(lines)


def _bar(name: str, limit: float, rows: list[dict]) -> str:
    met = sum(r[name] <= limit for r in rows)
    return f"- {name} <= {limit}: {met} of {len(rows)} clips"
