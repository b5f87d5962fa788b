"""The CMU walk mapped onto Rigify's human with its new corpus; prints JSON (issue 14, §6.3).

A GPR on the joints the CMU retarget map drives (:class:`rigmap.map.partial.SubsetMapping`)
is fitted on Rigify's human's training corpus (the biped's motions re-keyed,
:mod:`rigmap.animation.library.rigify_human`) posed by Blender, then
:func:`rigmap.map.clip.map_clip` maps a stretch of the walk, without and with computed-
Jacobian refinement. Reports the joint error over the mapped joints in cm RMS and as a
percentage of the rig's height, foot skate, the largest control jump, keys against frames,
and the seconds of every step. Blender rig evaluation is slow: keep the sizes small.

    PYTHONPATH=src .venv/bin/python benchmarks/map_cmu_rigify_human.py \\
        [--frames 48] [--step 2] [--gpr-points 150] [--refine-iterations 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from pathlib import Path

import numpy as np

from rigmap.animation.library import build_corpus
from rigmap.map import JointMap, tracks_from_bvh
from rigmap.map.clip import MapSettings, map_clip
from rigmap.map.partial import JointSubset, SubsetMapping
from rigmap.regression import GaussianProcessRegressor
from rigmap.regression.features import inverse_features
from rigmap.regression.kernels import MultiquadricKernel
from rigmap.rigs import load

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"
FEET = ("DEF-foot.L", "DEF-foot.R")
#: joint groups whose errors are reported apart (a name belongs to the first that matches)
GROUPS = {"legs": ("thigh", "shin", "foot", "toe"), "arms": ("arm", "hand", "f_"),
          "spine_head": ("spine",)}  # fmt: skip


def fit_mapping(rig, retarget, gpr_points: int, seconds: dict):
    started = time.perf_counter()
    Y = build_corpus(rig, "train", seed=0).values()
    seconds["corpus_s"] = time.perf_counter() - started
    started = time.perf_counter()
    pose = rig.pose(rig.expand_used(Y))
    seconds["pose_corpus_s"] = time.perf_counter() - started
    X = inverse_features(pose.positions, pose.cog, pose.cog_rotation, n_joints=rig.n_joints,
                         where="rigify_human corpus")  # fmt: skip
    subset = JointSubset("cmu", rig.name, tuple(retarget.joints), "DEF-spine", "DEF-thigh.L",
                         "DEF-thigh.R")  # fmt: skip
    regressor = GaussianProcessRegressor(
        MultiquadricKernel(), n_points=gpr_points, n_length_scales=5, cv_splits=2, progress=False
    )
    started = time.perf_counter()
    mapping = SubsetMapping.fit(rig, subset, X, Y, regressor)
    seconds["fit_s"] = time.perf_counter() - started
    return mapping, Y, len(Y)


def height_cm(rig) -> float:
    rest = rig.pose(rig.controls.defaults[None])
    return float(np.ptp((np.asarray(rest.positions) + np.asarray(rest.cog)[:, None])[0][:, 1]))


def joint_group(name: str) -> str:
    return next(g for g, parts in GROUPS.items() if any(part in name for part in parts))


def group_errors(result) -> dict:
    """RMS joint error (cm) per joint group: where the error comes from."""
    squared = ((result.achieved - result.targets) ** 2).sum(axis=2)
    groups = [joint_group(name) for name in result.joint_names]
    return {g: float(np.sqrt(squared[:, [k for k, h in enumerate(groups) if h == g]].mean()))
            for g in GROUPS}  # fmt: skip


def summary(result, rig_height: float) -> dict:
    rms = float(np.sqrt((result.frame_error_cm**2).mean()))
    return {
        "joint_error_rms_cm_by_group": group_errors(result),
        "joint_error_rms_cm": rms,
        "joint_error_rms_percent_of_height": 100.0 * rms / rig_height,
        "joint_error_max_cm": float(result.frame_error_cm.max()),
        "foot_skate_source_cm_per_frame": result.skate_source_cm,
        "foot_skate_result_cm_per_frame": result.skate_result_cm,
        "largest_jump_training_std": result.largest_jump_std,
        "keys": result.keys.key_count,
        "frames_times_keyed_controls": result.n_frames * len(result.keys.curves),
        "seconds": result.seconds,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=48, help="frames mapped (after --step)")
    parser.add_argument("--step", type=int, default=2, help="take every n-th mocap frame")
    parser.add_argument("--gpr-points", type=int, default=150)
    parser.add_argument("--refine-iterations", type=int, default=2)
    args = parser.parse_args()
    seconds: dict = {}
    rig = load("rigify_human")
    retarget = JointMap.from_yaml(ROOT / "conf/retarget/cmu_rigify_human.yaml")
    mapping, Y, n_train = fit_mapping(rig, retarget, args.gpr_points, seconds)
    targets = retarget.apply(rig, tracks_from_bvh(WALK))
    short = dataclasses.replace(
        targets, positions=targets.positions[:: args.step][: args.frames],
        fps=targets.fps / args.step,
    )  # fmt: skip
    std, median = Y.std(axis=0), np.median(Y, axis=0)
    std = np.where(std > 0, std, 1.0)
    settings = MapSettings(refine_iterations=0, feet=FEET, key_tolerance_cm=1.0,
                           hold=("*.IK_FK", "*.IK_Stretch", "*_follow"))  # fmt: skip
    rig_height = height_cm(rig)
    out = {"rig": rig.name, "source": WALK.name, "frames": len(short.positions),
           "fps": short.fps, "train_frames": n_train, "gpr_points": args.gpr_points,
           "mapped_joints": len(retarget.joints), "rig_height_cm": rig_height,
           "retarget_scale": targets.scale, "setup_seconds": seconds,
           "load_average_1min": os.getloadavg()[0]}  # fmt: skip
    for label, iterations in (("regression", 0), ("refined", args.refine_iterations)):
        result = map_clip(rig, short, mapping,
                          dataclasses.replace(settings, refine_iterations=iterations),
                          control_std=std, hold_values=median)  # fmt: skip
        out[label] = summary(result, rig_height)
    print(json.dumps(out, indent=2, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
