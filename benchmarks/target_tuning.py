"""The joint-space network tuned on each test clip it maps (issue #15, item 2); prints JSON.

For each rig and test clip: the fitted ``nn_joint_space`` model alone, then a copy tuned
on the clip's own pose rows (:func:`rigmap.regression.target_tuning.tune_on_targets`:
joint-space cost plus the neutral-pose and anchor terms, no controls), its joint error (cm², the
evaluation's measure), ground-truth error (training-std units) and the wall time of the
tuning plus prediction, with the machine's load average (a shared machine's wall clock
means something only beside it).

    PYTHONPATH=src .venv/bin/python benchmarks/target_tuning.py [--rigs quadruped biped]
        [--steps 40] [--learning-rate 3e-4] [--control-weight 0.01] [--models models] [--data data]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from rigmap.animation.corpus import Corpus
from rigmap.animation.posing import PoseTable
from rigmap.error_measures import control_std, ground_truth_error, joint_error
from rigmap.regression import load_regressor
from rigmap.regression.features import inverse_features
from rigmap.regression.target_tuning import TuningSettings, tune_on_targets
from rigmap.rigs import load
from rigmap.store import Layout, ModelId


def scores(rig, mapping, X, Y, std, kinds) -> dict:
    predicted = mapping.predict(X)
    posed = rig.evaluate(rig.expand_used(predicted))
    return {
        "joint_error_cm2": joint_error(posed, X[:, : 3 * rig.n_joints]).mean,
        "ground_truth_error": ground_truth_error(predicted, Y, std, kinds).mean,
    }


def measure(rig_name: str, layout: Layout, settings: TuningSettings) -> dict:
    rig = load(rig_name)
    mapping = load_regressor(layout.model(rig_name, ModelId("nn_joint_space")), rig=rig)
    names = list(rig.used_controls)
    train = Corpus.read(layout.corpus(rig_name, "train"), rig=rig_name, control_names=names)
    test = Corpus.read(layout.corpus(rig_name, "test"), rig=rig_name, control_names=names)
    poses = PoseTable.read(layout.poses(rig_name, "test"), rig=rig_name, n_joints=rig.n_joints)
    X_all = inverse_features(
        poses.positions(), poses.cog(), poses.cog_rotation(), n_joints=rig.n_joints, where="test"
    )
    Y_all, clips = test.values(), test.table["clip"].to_numpy()
    std = control_std(train.values())
    kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
    out = {}
    for clip in dict.fromkeys(clips):
        rows = clips == clip
        X, Y = X_all[rows], Y_all[rows]
        before = scores(rig, mapping, X, Y, std, kinds)
        started = time.perf_counter()
        tuned, report = tune_on_targets(mapping, rig, X, settings)
        tuned.predict(X)
        seconds = time.perf_counter() - started
        after = scores(rig, tuned, X, Y, std, kinds)
        out[str(clip)] = {
            "frames": int(rows.sum()),
            "network": before,
            "tuned": after,
            "tuning_seconds": seconds,
            "last_cost": report["last"],
        }
    frames = sum(c["frames"] for c in out.values())

    def average(part: str, key: str) -> float:
        return sum(c[part][key] * c["frames"] for c in out.values()) / frames

    return {
        "frames": frames,
        "network": {k: average("network", k) for k in ("joint_error_cm2", "ground_truth_error")},
        "tuned": {k: average("tuned", k) for k in ("joint_error_cm2", "ground_truth_error")},
        "tuning_seconds_total": sum(c["tuning_seconds"] for c in out.values()),
        "clips": out,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped"])
    parser.add_argument("--steps", type=int, default=TuningSettings.steps)
    parser.add_argument("--batch-size", type=int, default=TuningSettings.batch_size)
    parser.add_argument("--learning-rate", type=float, default=TuningSettings.learning_rate)
    parser.add_argument("--control-weight", type=float, default=TuningSettings.control_weight)
    parser.add_argument("--models", default="models")
    parser.add_argument("--data", default="data")
    args = parser.parse_args()
    settings = TuningSettings(args.steps, args.batch_size, args.learning_rate, args.control_weight)
    layout = Layout(data=Path(args.data), models=Path(args.models))
    result = {
        "settings": settings.__dict__,
        "load_average": os.getloadavg(),
        "rigs": {name: measure(name, layout, settings) for name in args.rigs},
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
