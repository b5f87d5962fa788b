"""The served map model: start-up, request latency and agreement with map_clip; prints JSON.

A subset mapping (effectors: pelvis, chest, head, hands, feet) is fitted on the biped's
train corpus, saved as the map pyfunc model (:mod:`rigmap.tracking.map_model`) and served
with ``mlflow models serve`` (:mod:`rigmap.tracking.model_server`). The request is the first
``--frames`` frames of the biped's first test clip. Timed: map_clip in this process, the
loaded pyfunc model, the served request (each ``--repeats`` times, best and median). The
machine may be shared, so the numbers carry the 1-minute load average around them.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/map_serve.py \\
        [--frames 30] [--points 300] [--refine-iterations 2] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

EFFECTORS = {"joints": ["pelvis", "spine_chest", "head", "hand_l", "hand_r", "foot_l", "foot_r"],
             "origin": "pelvis", "left": "foot_l", "right": "foot_r"}  # fmt: skip


def fitted_effector_mapping(rig, points: int):
    """The effector mapping on the train corpus, with its std and held (median) values."""
    from rigmap.animation.library import build_corpus
    from rigmap.map.partial import JointSubset, SubsetMapping
    from rigmap.regression import GaussianProcessRegressor
    from rigmap.regression.features import inverse_features
    from rigmap.regression.kernels import MultiquadricKernel

    Y = build_corpus(rig, "train", seed=0).values()
    pose = rig.pose(rig.expand_used(Y))
    X = inverse_features(pose.positions, pose.cog, pose.cog_rotation, n_joints=rig.n_joints,
                         where="biped corpus")  # fmt: skip
    subset = JointSubset.from_mapping(EFFECTORS, name="effectors", rig=rig)
    regressor = GaussianProcessRegressor(
        MultiquadricKernel(), n_points=points, n_length_scales=5, cv_splits=2, progress=False
    )
    return SubsetMapping.fit(rig, subset, X, Y, regressor), Y.std(axis=0), np.median(Y, axis=0)


def test_clip_targets(rig, subset, frames: int):
    from rigmap.animation.library import build_corpus
    from rigmap.map.joint_map import MappedTargets

    test = build_corpus(rig, "test", seed=0)
    clip = test.clip_table(test.clip_names[0]).iloc[:frames]
    pose = rig.pose(rig.expand_used(clip[test.controls].to_numpy(dtype=np.float64)))
    world = (np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :])[:, subset.columns(rig)]
    return MappedTargets(rig.name, subset.joints, world, float(test.fps),
                         test.clip_names[0], 1.0, (), ())  # fmt: skip


def timed(call, repeats: int) -> tuple[object, dict]:
    seconds, result = [], None
    for _ in range(repeats):
        started = time.perf_counter()
        result = call()
        seconds.append(time.perf_counter() - started)
    return result, {"best_s": min(seconds), "median_s": statistics.median(seconds)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--points", type=int, default=300)
    parser.add_argument("--refine-iterations", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    import mlflow

    from rigmap.map.clip import MapSettings, map_clip
    from rigmap.rigs import load
    from rigmap.tracking.map_model import MapModelParts, input_frame, save_map_model
    from rigmap.tracking.model_server import post_json, served_model

    load_before = os.getloadavg()[0]
    rig = load("biped")
    mapping, std, hold = fitted_effector_mapping(rig, args.points)
    targets = test_clip_targets(rig, mapping.subset, args.frames)
    settings = MapSettings(refine_iterations=args.refine_iterations, feet=("foot_l", "foot_r"))
    direct, direct_s = timed(lambda: map_clip(rig, targets, mapping, settings, control_std=std,
                                              hold_values=hold), args.repeats)  # fmt: skip
    request = input_frame(targets.positions, mapping.subset.joints)
    body = {"dataframe_split": {"columns": list(request.columns),
                                "data": request.to_numpy().tolist()}}  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="rigmap-map-serve-") as scratch:
        parts = MapModelParts(
            rig, mapping, settings, control_std=std, hold_values=hold, fps=targets.fps
        )
        folder = save_map_model(Path(scratch) / "model", parts)
        model = mlflow.pyfunc.load_model(str(folder))
        loaded, loaded_s = timed(lambda: model.predict(request), args.repeats)
        started = time.perf_counter()
        with served_model(folder) as url:
            start_s = time.perf_counter() - started
            (status, answer), served_s = timed(
                lambda: post_json(f"{url}/invocations", body), args.repeats
            )
    if status != 200:
        raise SystemExit(f"the served model answered {status}: {answer}")
    served = np.array([[row[c] for c in rig.control_names] for row in answer["predictions"]])
    print(json.dumps({
        "rig": rig.name, "subset": mapping.subset.name, "frames": args.frames,
        "gpr_points": args.points, "refine_iterations": args.refine_iterations,
        "map_clip": direct_s, "pyfunc_in_process": loaded_s,
        "served_request": served_s, "server_start_s": start_s,
        "served_frames_per_s": args.frames / served_s["best_s"],
        "max_abs_difference_served_vs_map_clip": float(np.abs(served - direct.controls).max()),
        "max_abs_difference_pyfunc_vs_map_clip": float(
            np.abs(loaded.to_numpy() - direct.controls).max()),
        "joint_error_rms_cm": float(np.sqrt((direct.frame_error_cm**2).mean())),
        "load_average_1min": [load_before, os.getloadavg()[0]],
    }, indent=2))  # fmt: skip


if __name__ == "__main__":
    main()
