"""What the joint-space network learns per second of training (issue #15); prints JSON lines.

For each rig, in one process and one after another, every variant of ``VARIANTS`` (settings
of ``regressor=nn_joint_space`` over the quick budget's config, ``conf/regressor/
nn_joint_space.yaml``) is fitted the way the fit stage fits it
(:func:`rigmap.regression.fitting.fit_regressor`, ``sampler=none``, seeded, one torch
thread) and scored on the rig's extreme test clips: joint error of the rig posed from the
predicted controls (cm², mean over frames), ground-truth error (training-std units, mean
over frames) and the training joint error on the corpus, with the fit's wall time and the
load average when it ended. On a shared machine compare times within one run only.

    PYTHONPATH=src .venv/bin/python benchmarks/joint_space_budget.py [--rigs quadruped biped]
        [--variants default steps300] [--data data] [--set epochs=4 batch_size=256]
        [--seeds 0 1 2]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import yaml

from rigmap.error_measures import ground_truth_error, joint_error
from rigmap.evaluation.methods import TestSet
from rigmap.regression.features import inverse_features
from rigmap.regression.fitting import fit_regressor, load_training_data, placement_of
from rigmap.regression.joint_space_network import JointSpaceNetworkRegressor
from rigmap.rigs import load

CONFIG = Path(__file__).resolve().parents[1] / "conf" / "regressor" / "nn_joint_space.yaml"

#: name -> overrides of the config's settings
_ONE_CYCLE = {"joint_learning_rate": 3e-3, "warmup": 0.1, "final_fraction": 0.01}
VARIANTS: dict[str, dict] = {
    "default": {},  # the config as it is (before this benchmark: 2 epochs of 512, 1e-3 cosine)
    # the joint-space phase longer, same schedule
    "e20": {"epochs": 20},
    # one-cycle: warm-up, higher peak, decay to a hundredth
    "e20_oc3": {"epochs": 20, "joint_learning_rate": 3e-3, "warmup": 0.1, "final_fraction": 0.01},
    "e20_oc10": {"epochs": 20, "joint_learning_rate": 1e-2, "warmup": 0.1, "final_fraction": 0.01},
    "e20_oc1": {"epochs": 20, "warmup": 0.1, "final_fraction": 0.01},
    # the sampler mix at the same rows (so the same steps): more wide draws, wider Gaussians
    "e20_oc3_wide3k": {
        "epochs": 20,
        "joint_learning_rate": 3e-3,
        "warmup": 0.1,
        "final_fraction": 0.01,
        "n_gaussian": 3000,
        "n_wide": 3000,
    },
    "e20_oc3_g3": {
        "epochs": 20,
        "joint_learning_rate": 3e-3,
        "warmup": 0.1,
        "final_fraction": 0.01,
        "gaussian_scale": 3.0,
    },
    "e20_oc3_pre5": {
        "epochs": 20,
        "joint_learning_rate": 3e-3,
        "warmup": 0.1,
        "final_fraction": 0.01,
        "pretrain_epochs": 5,
    },
    # batch vs epochs at about fixed wall time
    "e8_b128_oc3": {
        "epochs": 8,
        "batch_size": 128,
        "joint_learning_rate": 3e-3,
        "warmup": 0.1,
        "final_fraction": 0.01,
    },
    "e8_b64_oc3": {"epochs": 8, "batch_size": 64, **_ONE_CYCLE},
    "e8_b128_oc3_w02": {"epochs": 8, "batch_size": 128, "control_weight": 0.02, **_ONE_CYCLE},
    "e8_b128_oc3_h1024": {"epochs": 8, "batch_size": 128, "hidden": 1024, **_ONE_CYCLE},
    # over the session-28 default (the config now): a lower control weight, a shorter pretraining
    "w01": {"control_weight": 0.01},
    "pre5": {"pretrain_epochs": 5},
    # session 31: per-control draws around the corpus and the PCA draws (the config now has
    # n_local 48 000), fewer of them, none, fewer epochs, no wide draws
    "local0": {"n_local": 0},
    "local12k": {"n_local": 12000},
    "local24k": {"n_local": 24000},
    "local24k_wide0": {"n_local": 24000, "n_wide": 0},
    "local48k_e4": {"n_local": 48000, "epochs": 4},
    "local48k_e0": {"n_local": 48000, "epochs": 0},
    # session 33: the paper budget's width (h = 2048, its control-space network's) at the same
    # draws and steps, at the config's joint-space peak rate and a lower one
    "h2048": {"hidden": 2048},
    "h2048_jlr1e-3": {"hidden": 2048, "joint_learning_rate": 1e-3},
}


def base_settings() -> dict:
    config = yaml.safe_load(CONFIG.read_text())
    config.pop("_target_")
    config.update(seed=0, progress=False, threads=1)
    return config


def scores(rig, mapping, X, Y, std, kinds) -> dict:
    predicted = mapping.predict(X)
    posed = rig.evaluate(rig.expand_used(predicted))
    frames = joint_error(posed, X[:, : 3 * rig.n_joints])
    return {
        "joint_error_cm2": frames.mean,
        "median_frame_cm2": float(np.median(frames.per_frame)),
        "ground_truth_error": float(ground_truth_error(predicted, Y, std, kinds).mean),
    }


def measure(
    rig_name: str, data_dir: str, variants: list[str], extra: dict, seeds=(0,)
) -> list[dict]:
    rig = load(rig_name)
    data = load_training_data(rig, data_dir, "none")
    placement = placement_of(rig, data)
    test = TestSet.load(rig, Path(data_dir) / rig_name)

    def pose_rows(clip):
        where = f"test clip {clip.name!r}"
        return inverse_features(
            clip.positions, clip.cog, clip.cog_rotation, n_joints=rig.n_joints, where=where
        )

    X = np.concatenate([pose_rows(c) for c in test.clips])
    Y = np.concatenate([c.controls for c in test.clips])
    std, kinds = test.train_std, test.control_kinds
    out = []
    for name, seed in ((n, s) for n in variants for s in seeds):
        settings = {**base_settings(), **VARIANTS[name], **extra, "seed": seed}
        model = JointSpaceNetworkRegressor(**settings)
        rows = data.rows + model.n_draws
        started = time.perf_counter()
        mapping = fit_regressor(model, rig, data, placement, log=lambda _: None)
        seconds = time.perf_counter() - started
        train = scores(rig, mapping, data.features, data.controls, std, kinds)
        row = {
            "rig": rig_name,
            "variant": name,
            "seed": seed,
            "overrides": {**VARIANTS[name], **extra},
            "fit_seconds": round(seconds, 1),
            "joint_steps": model.epochs * -(-rows // model.batch_size),
            "test": scores(rig, mapping, X, Y, std, kinds),
            "train_joint_error_cm2": train["joint_error_cm2"],
            "load_average": [round(v, 2) for v in os.getloadavg()],
        }
        print(json.dumps(row), flush=True)
        out.append(row)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped"])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS))
    parser.add_argument("--data", default="data")
    parser.add_argument("--set", nargs="*", default=[], help="key=value (YAML) for every variant")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0], help="a fit per seed")
    args = parser.parse_args()
    extra = {k: yaml.safe_load(v) for k, v in (item.split("=", 1) for item in args.set)}
    for name in args.rigs:
        measure(name, args.data, args.variants, extra, args.seeds)


if __name__ == "__main__":
    main()
