"""Does damped-least-squares refinement keep the controls an animator would key? (issue #7)

Refines initial guesses for the first ``--frames`` frames of every test clip
of each rig and prints JSON with, per rig, guess, Jacobian and refinement
variant: the joint error (cm², mean over frames and the 3J coordinates) and
the ground-truth error (controls divided by their training-corpus std, as in
``rigmap.evaluation.metrics``) before and after, the share of controls left
outside their soft range, the largest move in training stds, and the
controls that carry most of the ground-truth error after refinement.

Variants (``--variants``; see ``VARIANTS``) differ in the metric the step is
damped in (plain Eq. 13 in each control's own unit, or normalised by the
training std, or by the soft range), λ (a number, or ``auto`` = Chiaverini's
rule) and whether iterates are kept inside the soft ranges.

Initial guesses (``--guesses``): ``nn`` (models/<rig>/nn-pca_gaussian-none),
``gpr`` (models/<rig>/gpr-none-multiquadric), ``script_noise`` (the rig's
retarget script plus Gaussian noise of ``--noise`` training stds; seeded) and
``training_mean``. Model inputs are built with whatever
``rigmap.regression.features.inverse_features`` is current; a model that no
longer accepts them is reported as skipped, with the reason.
``--jacobians``: ``finite_difference`` (computed on the rig every iteration)
and/or ``learned`` (the GPR-learned Jacobian of gpr-none-multiquadric,
predicted once per target).

    .venv/bin/python benchmarks/refine_drift.py [--rigs quadruped biped] [--frames 40]
        [--iterations 3] [--guesses nn gpr] [--variants ...] [--threads 1]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: name -> (control scale: None | "training_std" | "soft_range", λ, keep_in_range)
VARIANTS: dict[str, tuple[str | None, float | str, bool]] = {
    "eq13_lambda0.1": (None, 0.1, False),  # the old default: plain Eq. 13, λ = 0.1
    "eq13_auto": (None, "auto", False),
    "eq13_lambda0.1_in_range": (None, 0.1, True),
    "range_scaled_lambda0.1": ("soft_range", 0.1, False),
    "std_scaled_lambda0.1": ("training_std", 0.1, False),
    "std_scaled_lambda0.3": ("training_std", 0.3, False),
    "std_scaled_auto": ("training_std", "auto", False),  # auto = λ 1 on these rigs
    "std_scaled_lambda3": ("training_std", 3.0, False),
    "std_scaled_lambda10": ("training_std", 10.0, False),
    "std_scaled_lambda0.1_in_range": ("training_std", 0.1, True),
    "std_scaled_auto_in_range": ("training_std", "auto", True),  # the new default
}
DEFAULT_VARIANTS = (
    "eq13_lambda0.1",
    "eq13_auto",
    "eq13_lambda0.1_in_range",
    "range_scaled_lambda0.1",
    "std_scaled_lambda0.1",
    "std_scaled_auto",
    "std_scaled_auto_in_range",
)
MODEL_FOLDERS = {"nn": "nn-pca_gaussian-none", "gpr": "gpr-none-multiquadric"}
LEARNED_JACOBIAN_FOLDER = "gpr-none-multiquadric/learned_jacobian"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped"])
    parser.add_argument("--frames", type=int, default=40, help="first frames of each test clip")
    parser.add_argument("--iterations", type=int, default=3, help="DLS iteration cap")
    parser.add_argument("--tolerance", type=float, default=1e-4, help="cm², stop a frame below")
    parser.add_argument("--guesses", nargs="+", default=["nn", "gpr"],
                        choices=["nn", "gpr", "script_noise", "training_mean"])  # fmt: skip
    parser.add_argument("--jacobians", nargs="+", default=["finite_difference"],
                        choices=["finite_difference", "autodiff", "learned"])  # fmt: skip
    parser.add_argument("--variants", nargs="+", default=list(DEFAULT_VARIANTS),
                        choices=list(VARIANTS))  # fmt: skip
    parser.add_argument("--noise", type=float, default=0.5, help="script_noise: training stds")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (shared machine)")
    parser.add_argument("--data", type=Path, default=ROOT / "data")
    parser.add_argument("--models", type=Path, default=ROOT / "models")
    args = parser.parse_args(argv)

    import torch

    torch.set_num_threads(args.threads)
    report = {
        "benchmark": "refine_drift",
        "frames_per_clip": args.frames,
        "iterations": args.iterations,
        "tolerance_cm2": args.tolerance,
        "units": {
            "joint_error": "cm², mean over frames and the 3J joint coordinates",
            "ground_truth_error": "dimensionless: controls / training-corpus std, squared, mean",
            "largest_move_std": "largest |refined - initial| of any control, in training stds",
            "outside_soft_range": "share of (frame, control) values outside [lower, upper]",
        },
        "variants": {
            name: {"control_scale": s, "damping": lam, "keep_in_range": r}
            for name, (s, lam, r) in VARIANTS.items()
            if name in args.variants
        },
        "load_average": os.getloadavg()[0],
        "rigs": {},
    }
    for rig_name in args.rigs:
        report["rigs"][rig_name] = measure_rig(rig_name, args)
        print(f"{rig_name}: done", file=sys.stderr, flush=True)
    print(json.dumps(report, indent=2))


def measure_rig(rig_name: str, args) -> dict:
    from rigmap.evaluation.methods import TestSet
    from rigmap.rigs import load

    rig = load(rig_name)
    test_set = TestSet.load(rig, args.data / rig_name).first_frames(args.frames)
    problem = Problem(rig, test_set)
    out: dict = {"frames": len(problem.targets), "clips": [c.name for c in test_set.clips]}
    rng = np.random.default_rng(args.seed)
    for guess in args.guesses:
        try:
            start = initial_guess(guess, problem, args, rng)
        except Exception as error:  # a model that no longer fits the features: say why
            out[guess] = {"skipped": f"{type(error).__name__}: {error}"}
            continue
        entry: dict = {"initial": problem.scores(start)}
        for jacobian_name in args.jacobians:
            try:
                source = jacobian_source(jacobian_name, problem, args)
            except Exception as error:
                entry[jacobian_name] = {"skipped": f"{type(error).__name__}: {error}"}
                continue
            rows = {}
            for variant in args.variants:
                rows[variant] = problem.refine(start, source, VARIANTS[variant], args)
                summary = rows[variant]
                print(
                    f"{rig_name} {guess} {jacobian_name} {variant}: joint "
                    f"{entry['initial']['joint_error']:.4g} -> {summary['joint_error']:.4g} cm², "
                    f"ground truth {entry['initial']['ground_truth_error']:.4g} -> "
                    f"{summary['ground_truth_error']:.4g} ({summary['seconds']:.3g} s)",
                    file=sys.stderr,
                    flush=True,
                )
            entry[jacobian_name] = rows
        out[guess] = entry
    return out


class Problem:
    """The targets, animator controls and scales of one rig's test frames."""

    def __init__(self, rig, test_set):
        self.rig = rig
        self.test_set = test_set
        clips = test_set.clips
        self.targets = np.concatenate([c.positions for c in clips])
        self.cog = np.concatenate([c.cog for c in clips])
        self.cog_rotation = np.concatenate([c.cog_rotation for c in clips])
        self.truth = np.concatenate([c.controls for c in clips])
        self.clip_of_frame = np.concatenate([[c.name] * len(c) for c in clips])
        used = rig.controls.used_indices
        self.lower, self.upper = rig.controls.lower[used], rig.controls.upper[used]
        self.scales = {
            None: None,
            "training_std": test_set.train_std,
            "soft_range": self.upper - self.lower,
        }

    def features(self) -> np.ndarray:
        from rigmap.regression.features import inverse_features

        return inverse_features(
            self.targets,
            self.cog,
            self.cog_rotation,
            n_joints=self.rig.n_joints,
            where=f"test frames of rig {self.rig.name!r}",
        )

    def scores(self, Y_used: np.ndarray, start: np.ndarray | None = None) -> dict:
        from rigmap.evaluation.metrics import ground_truth_error, joint_error

        X = self.rig.evaluate(self.rig.expand_used(Y_used))
        joints = joint_error(X, self.targets)
        names = self.test_set.control_names
        truth = ground_truth_error(
            Y_used, self.truth, self.test_set.train_std, self.test_set.control_kinds, names=names
        )
        outside = (Y_used < self.lower - 1e-9) | (Y_used > self.upper + 1e-9)
        result = {
            "joint_error": joints.mean,
            "ground_truth_error": truth.mean,
            "ground_truth_error_by_kind": truth.per_kind,
            "outside_soft_range": float(outside.mean()),
            "clips": {
                clip: {
                    "joint_error": float(joints.per_frame[self.clip_of_frame == clip].mean()),
                    "ground_truth_error": float(truth.per_frame[self.clip_of_frame == clip].mean()),
                }
                for clip in dict.fromkeys(self.clip_of_frame)
            },
        }
        if start is not None:
            std = np.where(self.test_set.train_std > 0, self.test_set.train_std, np.nan)
            move = np.abs(Y_used - start) / std
            result["largest_move_std"] = float(np.nanmax(move))
            per_control = np.nanmean(((Y_used - self.truth) / std) ** 2, axis=0)
            worst = np.argsort(-np.nan_to_num(per_control))[:5]
            result["share_of_ground_truth_error_in_worst_5_controls"] = float(
                np.nansum(per_control[worst]) / np.nansum(per_control)
            )
            result["worst_controls"] = [
                {
                    "name": names[i],
                    "kind": self.test_set.control_kinds[i],
                    "training_std": float(self.test_set.train_std[i]),
                    "mean_abs_move": float(np.abs(Y_used - start)[:, i].mean()),
                    "ground_truth_error": float(per_control[i]),
                }
                for i in worst
            ]
        return result

    def refine(self, start: np.ndarray, source, variant, args) -> dict:
        from rigmap.refine import damped_least_squares

        scale_name, damping, keep_in_range = variant
        began = time.perf_counter()
        result = damped_least_squares(
            self.rig,
            start,
            self.targets,
            source,
            damping=damping,
            tolerance=args.tolerance,
            max_iterations=args.iterations,
            control_scale=self.scales[scale_name],
            keep_in_range=keep_in_range,
        )
        seconds = time.perf_counter() - began
        scores = self.scores(result.Y_used, start)
        scores.update(
            seconds=seconds,
            rig_evaluations=result.rig_evaluations,
            mean_iterations=float(result.iterations.mean()),
        )
        return scores


def initial_guess(guess: str, problem: Problem, args, rng: np.random.Generator) -> np.ndarray:
    if guess in MODEL_FOLDERS:
        from rigmap.regression import load_regressor

        folder = args.models / problem.rig.name / MODEL_FOLDERS[guess]
        model = load_regressor(folder, rig=problem.rig)
        return np.asarray(model.predict(problem.features()), dtype=np.float64)
    std = problem.test_set.train_std
    if guess == "script_noise":
        from rigmap.retarget.script import script_retarget

        Y = script_retarget(problem.rig, problem.targets, problem.cog, problem.cog_rotation).Y_used
        return Y + args.noise * std * rng.standard_normal(Y.shape)
    if guess == "training_mean":
        from rigmap.animation.corpus import Corpus

        rig = problem.rig
        path = args.data / rig.name / "corpus" / "train.parquet"
        train = Corpus.read(path, rig=rig.name, control_names=rig.used_controls, split="train")
        mean = train.table[rig.used_controls].to_numpy(dtype=np.float64).mean(axis=0)
        return np.tile(mean, (len(problem.targets), 1))
    raise ValueError(f"unknown guess {guess!r}")


def jacobian_source(name: str, problem: Problem, args):
    from rigmap.refine import ComputedJacobian, PredictedJacobian

    if name != "learned":
        return ComputedJacobian(problem.rig, name)
    from rigmap.regression import load_learned_jacobian

    folder = args.models / problem.rig.name / LEARNED_JACOBIAN_FOLDER
    model = load_learned_jacobian(folder, rig=problem.rig)
    return PredictedJacobian(model, problem.features())


if __name__ == "__main__":
    main()
