"""Incremental refinement (002 §3, Fig 2) and the MLS estimator (§4.4) on the biped; JSON.

The biped in rig mode (``conf/edits/default.yaml``'s subject: the examples are a walk and
a stand, the held-out clips its ``heldout_motions``, motions the examples never play;
``benchmarks/results/edits_refine_s30.json`` was measured on the earlier held-out set,
every library motion replayed with another seed's variation).
A procedural edit is learned from the examples (mirrored left/right, §7.1) and applied to
the held-out clips; then for 5 rounds the "artist" fixes ``--per-round`` segments of
``--segment`` frames to the edit's ground truth, chosen by the highest predictive variance
of the configuration predictor (the suggestion; ``--choices`` may add ``variance_clips``,
the suggestion spread over clips, :mod:`rigmap.edits.incremental`) or at random over
``--random-seeds`` seeds (``--seed`` on: one random run is one draw), and the model is
refitted, its hyper-parameters searched from the paper's initial values ("cold") or
from the last round's ("warm", ours). Printed per start: every run's rounds (frames
authored, edit error in std units² over all held-out frames and over the frames not
fixed, joint RMSE (cm), transfer ratio ρ, refit seconds, the segments fixed) and a
per-round summary, each choice's edit error beside random's mean, std, min and max.
Beside it: the edit error of the GP and of moving least squares after round 0.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/edits_refine.py [--edit arm_swing]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import yaml

from rigmap.edits.incremental import CHOICES, compare_choices
from rigmap.edits.mirror import subject_mirror
from rigmap.edits.propagation import EditModel
from rigmap.edits.scoring import Tally, score_clip
from rigmap.edits.study import edits_for, load_study, weights_from

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--edit", default="arms_forward_walking")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--per-round", type=int, default=2)
    parser.add_argument("--segment", type=int, default=12)  # frames (0.5 s at 24 fps): ours
    parser.add_argument("--seed", type=int, default=0)  # random's first seed
    parser.add_argument("--random-seeds", type=int, default=5)  # ours
    parser.add_argument("--choices", nargs="+", default=["variance"],
                        choices=[c for c in CHOICES if c != "random"])  # fmt: skip
    parser.add_argument("--no-mirror", action="store_true")
    parser.add_argument("--starts", nargs="+", default=["cold", "warm"], choices=["cold", "warm"])
    parser.add_argument("--no-estimators", action="store_true")
    args = parser.parse_args()
    settings = yaml.safe_load((ROOT / "conf/edits/default.yaml").read_text())
    catalogue = {p.stem: yaml.safe_load(p.read_text()) for p in (ROOT / "conf/edit").glob("*.yaml")}
    data = load_study("biped", settings["subjects"]["biped"])
    edit = edits_for(catalogue, [args.edit], "rig")[args.edit]
    mirror = None if args.no_mirror else subject_mirror(data.subject)
    examples = [(s, edit.apply(s.track)) for s in data.train]
    truths = [edit.apply(s.track) for s in data.heldout]

    def model(estimator="gp"):
        return EditModel(data.subject.joints, weights_from(settings["weights"]),
                         residual=bool(settings["residual"]), estimator=estimator)  # fmt: skip

    estimators = {}
    for estimator in () if args.no_estimators else ("gp", "mls"):
        start = time.perf_counter()
        fitted = model(estimator).fit(examples, data.scale, mirror=mirror)
        fit_s = time.perf_counter() - start
        tally = Tally()
        for source, truth in zip(data.heldout, truths, strict=True):
            result = fitted.apply(source)
            tally.merge(score_clip(source.track, truth, result, data.scale,
                                   data.subject.relative_cm))  # fmt: skip
        summary = tally.summary()
        estimators[estimator] = {
            key: summary[key]
            for key in ("edit_error_std", "source_error_std", "joint_rmse_cm",
                        "source_joint_rmse_cm", "transfer", "leak_std", "jerk_ratio")
        } | {"fit_s": fit_s}  # fmt: skip
    rounds = {
        start: compare_choices(
            model, data.scale, examples, data.heldout, truths, choices=args.choices,
            random_seeds=args.random_seeds, seed=args.seed, rounds=args.rounds,
            per_round=args.per_round, segment=args.segment, mirror=mirror,
            relative_cm=data.subject.relative_cm, warm_start=start == "warm",
        )
        for start in args.starts
    }  # fmt: skip
    print(json.dumps({
        "edit": args.edit,
        "mirrored": mirror is not None,
        "examples_frames": sum(s.track.n_frames for s in data.train),
        "heldout_clips": len(data.heldout),
        "heldout_frames": sum(s.track.n_frames for s in data.heldout),
        "estimators_round_0": estimators,
        "rounds": rounds,
        "load_average_1min": os.getloadavg()[0],
    }, indent=2))  # fmt: skip


if __name__ == "__main__":
    main()
