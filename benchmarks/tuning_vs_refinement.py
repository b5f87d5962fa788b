"""Tuning on the clip against more refinement iterations, timed as Table 1 times them (issue #15).

Issue #15 asks the joint-space network tuned on the target clip to reach 0.5 cm² in less
wall time than NN & Computed Jacobian. This runs, in one process and one after another,
every variant of ``VARIANTS`` through the evaluation's own
:func:`rigmap.evaluation.methods.run_method` (one untimed warm-up frame per clip, the rest
timed end to end) on each rig's test clips, and prints JSON lines: joint error (cm²),
ground-truth error (training-std units), total seconds and the load average when it ended.
On a shared machine compare times within one run only; the control-space NN & CJ runs
first and last so the spread of the clock shows.

The refinement settings are the pipeline's ``nn_joint_space_computed_jacobian`` (from
params.yaml) with ``max_iterations`` changed; tuning is
:class:`rigmap.regression.target_tuning.TunedOnTarget` with
:class:`~rigmap.regression.target_tuning.TuningSettings` changed.

    PYTHONPATH=src .venv/bin/python benchmarks/tuning_vs_refinement.py [--rigs quadruped biped]
        [--models models] [--data data] [--variants nn_cj3 js_cj6 tuned80]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import torch
import yaml

from rigmap.evaluation.methods import (
    ComputedJacobianRefinement,
    Method,
    NoRefinement,
    RegressorGuess,
    TestSet,
    run_method,
)
from rigmap.regression import load_regressor
from rigmap.regression.target_tuning import TunedOnTarget, TuningSettings
from rigmap.rigs import load
from rigmap.store import Layout, ModelId

#: name -> (regressor, refinement iterations or 0, tuning settings or None)
VARIANTS = {
    "nn_cj3": ("nn", 3, None),
    "nn_cj10": ("nn", 10, None),  # the paper budget's iteration cap (experiment=paper)
    "js": ("nn_joint_space", 0, None),
    "js_cj3": ("nn_joint_space", 3, None),
    "js_cj4": ("nn_joint_space", 4, None),
    "js_cj6": ("nn_joint_space", 6, None),
    "tuned80": ("nn_joint_space", 0, {"steps": 80}),
    "tuned10_cj2": ("nn_joint_space", 2, {"steps": 10}),
    "nn_cj3_again": ("nn", 3, None),
}
MODELS = {"nn": ModelId("nn", "pca_gaussian"), "nn_joint_space": ModelId("nn_joint_space")}


def measure(rig_name: str, layout: Layout, refine: dict, variants: list[str]) -> list[dict]:
    rig = load(rig_name)
    test_set = TestSet.load(rig, layout)
    loaded = {}
    out = []
    for name in variants:
        regressor, iterations, tune = VARIANTS[name]
        if regressor not in loaded:
            loaded[regressor] = load_regressor(layout.model(rig_name, MODELS[regressor]), rig=rig)
        plain = {k: v for k, v in refine.items() if k != "_target_"}  # the class is ours
        settings = dict(plain, max_iterations=iterations) if iterations else None
        refiner = ComputedJacobianRefinement(**settings) if settings else NoRefinement()
        method = Method(name, RegressorGuess(regressor), refiner, tune=tune)
        mapping = loaded[regressor]
        if method.tune is not None:
            mapping = TunedOnTarget(mapping, rig, TuningSettings(**method.tune))
        evaluation = run_method(rig, method, test_set, regressor=mapping)
        average = evaluation.result.average()
        row = {
            "rig": rig_name,
            "variant": name,
            "joint_error_cm2": average["joint_error"],
            "ground_truth_error": average["ground_truth_error"],
            "total_time_s": average["total_time_s"],
            "load_average": os.getloadavg()[0],
        }
        print(json.dumps(row), flush=True)
        out.append(row)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped"])
    parser.add_argument("--models", default="models")
    parser.add_argument("--data", default="data")
    parser.add_argument("--params", default="params.yaml")
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = parser.parse_args()
    torch.set_num_threads(1)  # as the pipeline's refinement and tuning (threads: 1)
    params = yaml.safe_load(Path(args.params).read_text())
    refine = params["method"]["nn_joint_space_computed_jacobian"]["refine"]
    layout = Layout(data=Path(args.data), models=Path(args.models))
    for rig_name in args.rigs:
        measure(rig_name, layout, refine, args.variants)


if __name__ == "__main__":
    main()
