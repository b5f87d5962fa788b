"""Tuning on the clip with L-BFGS instead of Adam (issue #15, a probe); prints JSON lines.

The cost is :func:`rigmap.regression.target_tuning.tune_on_targets`' (joint term on the clip
and the rest pose, control weight 0.01 against the untuned network's controls), minimised
over all the clip's rows at once by ``torch.optim.LBFGS`` (strong-Wolfe line search) with at
most ``evals`` cost evaluations, each one pass through the rig forward and backward: the
same price as one Adam step of ``tune_on_targets``. Scored as ``benchmarks/target_tuning.py``
scores (frame-weighted means over the test clips; seconds summed over the clips).

    PYTHONPATH=src .venv/bin/python benchmarks/target_tuning_lbfgs.py EVALS [LR]
"""

from __future__ import annotations

import copy
import json
import os
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rigmap.animation.corpus import Corpus
from rigmap.animation.posing import PoseTable
from rigmap.error_measures import control_std
from rigmap.regression import load_regressor
from rigmap.regression.features import inverse_features
from rigmap.regression.joint_space_training import joint_space_cost
from rigmap.regression.mapping import InverseMapping
from rigmap.regression.rig_forward import PlacedRigForward
from rigmap.regression.target_tuning import _tuning_data
from rigmap.rigs import load
from rigmap.store import Layout, ModelId
from target_tuning import scores


def tune_lbfgs(mapping, rig, X, evals: int, lr: float) -> InverseMapping:
    """A copy of ``mapping`` tuned on the pose rows ``X`` by L-BFGS (``evals`` cost passes)."""
    forward = PlacedRigForward(rig, mapping.placement, who="tuning on the target")
    tuned = copy.deepcopy(mapping.regressor)
    data = _tuning_data(forward, mapping, X)
    network = tuned.network_
    network.train()
    optimizer = torch.optim.LBFGS(
        list(network.parameters()),
        lr=lr,
        max_iter=evals,
        max_eval=evals,
        history_size=10,
        line_search_fn="strong_wolfe",
    )
    rows = torch.arange(len(data.inputs))

    def closure():
        optimizer.zero_grad()
        joint, control = joint_space_cost(network, forward, data, rows)
        cost = joint + 0.01 * control
        cost.backward()
        return cost

    optimizer.step(closure)
    network.eval()
    return InverseMapping(tuned, mapping.placement)


def measure(rig_name: str, layout: Layout, evals: int, lr: float) -> dict:
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
    total = {"joint": 0.0, "truth": 0.0, "frames": 0, "seconds": 0.0}
    for clip in dict.fromkeys(clips):
        rows = clips == clip
        X, Y = X_all[rows], Y_all[rows]
        started = time.perf_counter()
        tuned = tune_lbfgs(mapping, rig, X, evals, lr)
        tuned.predict(X)
        total["seconds"] += time.perf_counter() - started
        score, n = scores(rig, tuned, X, Y, std, kinds), int(rows.sum())
        total["joint"] += score["joint_error_cm2"] * n
        total["truth"] += score["ground_truth_error"] * n
        total["frames"] += n
    return {
        "rig": rig_name,
        "evals": evals,
        "lr": lr,
        "joint_error_cm2": total["joint"] / total["frames"],
        "ground_truth_error": total["truth"] / total["frames"],
        "seconds": total["seconds"],
        "load_average": os.getloadavg()[0],
    }


def main() -> None:
    torch.set_num_threads(1)
    layout = Layout(data=Path("data"), models=Path("models"))
    evals = int(sys.argv[1])
    lr = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
    for rig_name in ("quadruped", "biped"):
        print(json.dumps(measure(rig_name, layout, evals, lr)), flush=True)


if __name__ == "__main__":
    main()
