"""The learned stand-in of a Blender rig (issue #39): how close, how fast; prints JSON.

For each rig: the corpus frames and draws made the way the joint-space training makes them
(:func:`rigmap.regression.joint_space_training.draw_training_controls`, root channels at
zero; the quick budget's mix of ``conf/regressor/nn_joint_space.yaml`` divided by
``--divide``) are posed by the real rig's worker pool (timed: the real rig's poses/s), a
stand-in is fitted on them (:func:`rigmap.regression.stand_in.fit_stand_in`, timed), and

- its held-out joint RMS (cm, the rows the fit kept out), over all joints and the five
  worst, and the COG's;
- its RMS on the rig's test clips (root channels zeroed), posed by the real rig: the
  frames Table 1 scores, which the draws may not cover;
- its poses/s on the same batch (float32, no gradient) and one forward + backward at 128
  rows, against the real rig's poses/s in the same run (on a shared machine compare
  within one run only).

    PYTHONPATH=src .venv/bin/python benchmarks/stand_in.py [--rigs rigify_wolf blend_file:hero]
        [--divide 8] [--workers 2] [--out benchmarks/results/stand_in.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
import yaml

from rigmap.animation.corpus import Corpus
from rigmap.error_measures import joint_error, joint_rms
from rigmap.regression.fitting import load_training_data, placement_of
from rigmap.regression.joint_space_training import draw_training_controls
from rigmap.regression.stand_in import StandInSettings, fit_stand_in
from rigmap.rigs import load
from rigmap.store.layout import Layout

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "conf" / "regressor" / "nn_joint_space.yaml"
BLEND_FILE = ROOT / "conf" / "rig" / "blend_file.yaml"  # the pipeline's rig=blend_file
#: the rigs by their name in data/, and how rigmap loads each
SPECS = {
    "rigify_wolf": {"name": "rigify_wolf"},
    "blend_file:hero": {
        **{k: v for k, v in yaml.safe_load(BLEND_FILE.read_text()).items() if k[0] != "_"},
        "path": str(ROOT / "data" / "blend_fixture" / "hero.blend"),
        "armature": "rig",
    },
}


def measure(name: str, divide: int, workers: int, settings: StandInSettings) -> dict:
    config = yaml.safe_load(CONFIG.read_text())
    sizes = {k: int(config[k]) // divide for k in ("n_gaussian", "n_local", "n_wide")}
    rig = load({**SPECS[name], "workers": workers})
    try:
        data = load_training_data(rig, ROOT / "data", "none")
        placement = placement_of(rig, data)
        root = [c.index for c in placement.channels]
        corpus = data.controls[: data.corpus_rows].copy()
        corpus[:, root] = 0.0
        drawn = draw_training_controls(
            rig,
            placement,
            corpus,
            sizes["n_gaussian"],
            float(config["gaussian_scale"]),
            sizes["n_wide"],
            np.random.default_rng(0),
            n_local=sizes["n_local"],
            local_scale=float(config["local_scale"]),
        )
        controls = np.concatenate([corpus, drawn])
        rig.pose(rig.expand_used(controls[: 2 * workers]))  # start every worker
        started = time.perf_counter()
        pose = rig.pose(rig.expand_used(controls))
        real_seconds = time.perf_counter() - started
        stand_in = fit_stand_in(rig, controls, pose, root, settings, progress=False)
        started = time.perf_counter()
        stand_in.pose(rig.expand_used(controls))
        stand_in_seconds = time.perf_counter() - started
        step_ms = _forward_backward_ms(stand_in, rig.expand_used(controls[:128]))
        test = _test_clip_rms(rig, stand_in, root)
    finally:
        rig.close()
    worst = sorted(stand_in.fit.heldout_rms_per_joint_cm.items(), key=lambda kv: -kv[1])[:5]
    return {
        "rig": name,
        "used_controls": len(rig.used_controls),
        "joints": rig.n_joints,
        "rows": {"corpus": len(corpus), **sizes, "all": len(controls)},
        "real_rig": {
            "workers": workers,
            "seconds": round(real_seconds, 2),
            "poses_per_s": round(len(controls) / real_seconds, 1),
        },
        "stand_in": {
            "settings": asdict(settings),
            "fit_seconds": round(stand_in.fit.seconds, 2),
            "heldout_rows": stand_in.fit.heldout_rows,
            "heldout_joint_rms_cm": round(stand_in.fit.heldout_rms_cm, 4),
            "heldout_cog_rms_cm": round(stand_in.fit.heldout_cog_rms_cm, 4),
            "heldout_worst_joints_cm": {k: round(v, 4) for k, v in worst},
            "test_clips": test,
            "poses_per_s": round(len(controls) / stand_in_seconds, 1),
            "forward_backward_128_rows_ms": round(step_ms, 2),
        },
        "poses_per_s_ratio": round(real_seconds / stand_in_seconds, 1),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }


def _forward_backward_ms(stand_in, controls: np.ndarray, repeats: int = 20) -> float:
    batch = torch.from_numpy(controls.astype(np.float32))
    best = float("inf")
    for _ in range(repeats):
        at = batch.clone().requires_grad_(True)
        started = time.perf_counter()
        stand_in.pose(at).positions.square().sum().backward()
        best = min(best, time.perf_counter() - started)
    return 1000 * best


def _test_clip_rms(rig, stand_in, root: list[int]) -> dict:
    path = Layout(data=ROOT / "data").corpus(rig.name, "test")
    corpus = Corpus.read(path, rig=rig.name, control_names=rig.used_controls, split="test")
    controls = corpus.values().copy()
    controls[:, root] = 0.0
    real = rig.pose(rig.expand_used(controls))
    guess = stand_in.pose(rig.expand_used(controls))
    errors = joint_error(guess.positions, real.positions)
    return {
        "frames": len(controls),
        "joint_rms_cm": round(joint_rms(errors.mean), 4),
        "worst_frame_rms_cm": round(joint_rms(float(errors.per_frame.max())), 4),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=list(SPECS), choices=list(SPECS))
    parser.add_argument("--divide", type=int, default=8, help="draws: the config's / this")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--epochs", type=int, default=StandInSettings.epochs)
    parser.add_argument("--out", type=Path, help="also write the results here (JSON)")
    args = parser.parse_args()
    settings = StandInSettings(epochs=args.epochs)
    results = []
    for name in args.rigs:
        results.append(measure(name, args.divide, args.workers, settings))
        print(json.dumps(results[-1]), flush=True)
        if args.out:  # after every rig, so a later rig's failure keeps the earlier ones
            args.out.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
