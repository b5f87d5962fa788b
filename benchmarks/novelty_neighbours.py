"""How steady the joint-space network's confidence is: novelty over k neighbours; JSON.

The joint-space network's novelty is measured to its 54 000 draws too
(:mod:`rigmap.evaluation.novelty`). Here, on the test clips, the Spearman correlation of
its per-frame joint error (the committed ``metrics/<rig>/methods/nn_joint_space-none.csv``)
with the mean RMS joint distance to the k nearest learned frames, k = 1, 3, 5, 10, for
the fit's own draws (``draw seed`` = the model's seed) and for other draw sets of the
same settings (what another seed of the same config could have drawn), and for the GPR
and the control-space network against the corpus.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/novelty_neighbours.py [--rigs biped]
"""

from __future__ import annotations

import argparse
import copy
import json
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import spearmanr
from sklearn.neighbors import NearestNeighbors

from rigmap.evaluation.methods import TestSet
from rigmap.evaluation.retargeter import pose_rows as _pose_rows
from rigmap.regression import load_regressor
from rigmap.rigs import load
from rigmap.store import Layout

NEIGHBOURS = (1, 3, 5, 10)


def correlations(reference, queries, errors, n_joints) -> dict[str, float]:
    width = 3 * n_joints
    search = NearestNeighbors(n_neighbors=max(NEIGHBOURS)).fit(reference[:, :width])
    distances, _ = search.kneighbors(queries[:, :width])
    return {
        str(k): float(spearmanr(distances[:, :k].mean(axis=1), errors).statistic)
        for k in NEIGHBOURS
    }


def rig_report(name: str, models: Path, data: Path, metrics: Path, seeds) -> dict:
    rig = load(name)
    test_set = TestSet.load(rig, Layout(data=data))
    rows = np.concatenate(
        [_pose_rows(rig, c.name, c.positions, c.cog, c.cog_rotation) for c in test_set.clips]
    )
    report = {}
    for model, method in (
        ("nn_joint_space-none-none", "nn_joint_space-none"),
        ("gpr-none-gaussian", "gpr-none"),
        ("nn-pca_gaussian-none", "nn-pca_gaussian"),
    ):
        mapping = load_regressor(models / name / model, rig)
        placement, regressor = mapping.placement, mapping.regressor
        errors = pd.read_csv(metrics / name / "methods" / f"{method}.csv")["joint_error"]
        inputs = placement.inputs(test_set.train_poses)
        queries = placement.inputs(rows)
        if not hasattr(regressor, "learned_inputs"):
            report[method] = {"corpus": correlations(inputs, queries, errors, rig.n_joints)}
            continue
        targets = placement.targets(test_set.train_controls, test_set.train_poses)
        by_seed = {}
        for seed in seeds:
            other = copy.copy(regressor)  # the same settings, another seed's draws
            other.seed = seed
            drawn = other._draw(rig, placement, targets)[0]
            reference = np.concatenate([inputs, drawn])
            by_seed[f"draw seed {seed}"] = correlations(reference, queries, errors, rig.n_joints)
        report[method] = {"fit's draw seed": int(regressor.seed), **by_seed}
    return report


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    parser.add_argument("--models", type=Path, default=Path("models"))
    parser.add_argument("--data", type=Path, default=Path("data"))
    parser.add_argument("--metrics", type=Path, default=Path("metrics"))
    args = parser.parse_args()
    out = {
        "measure": "Spearman(mean RMS joint distance to the k nearest learned frames, joint error)",
        "rigs": {
            name: rig_report(name, args.models, args.data, args.metrics, args.seeds)
            for name in args.rigs
        },
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
