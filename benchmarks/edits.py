"""Edit propagation speed (002 §7.3): refit time at 2 × 550 frames and prediction frames/s; JSON.

The paper: "Estimating the parameters for the Gaussian processes consumes around 30
seconds, and producing frame estimations … proceeds at 2–3 frames per second", with the
training data mirrored (550 frames → 1 100). Here: the skeleton-mode CMU walks, two
550-frame walking stretches (one of each clip, 1 100 frames, 837 kinematic features) and
the ``arms_forward_walking`` edit; the refit is both GPs (≤ 100 L-BFGS-B iterations
each), fitted three ways in the same run: ``"first"``, the first implementation's
objective (full-matrix gradient, kept here to measure against), ``"lbfgs"``, the default
(the same 3-D L-BFGS-B, lower-triangle gradient sums), and ``"profile"`` (ℓ searched with
σ_f and σ_n profiled out by one eigendecomposition per ℓ, ``rigmap.edits.gp``); the
optima beside each other and the largest differences of their predictions are printed;
prediction is both GPs plus the banded solve on the whole second clip (1 247 frames at
120 fps). The machine may be shared: the 1-minute load average is printed, and CPU
seconds of this process beside the wall-clock ones.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/edits.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import yaml
from scipy.linalg import cho_factor, cho_solve, lapack

import rigmap.rigs
from rigmap.edits.gp import SharedGP
from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import EditModel
from rigmap.edits.representation import ChannelScale
from rigmap.edits.subjects import leg_length_cm_per_unit, skeleton_clip, skeleton_subject

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"


class FirstSharedGP(SharedGP):
    """The first implementation's objective, verbatim: full matrices, ``K⁻¹`` symmetrised."""

    def _objective(self, theta):
        length, signal, noise = np.exp(theta)
        n, d = self.Y_.shape
        sq = self._sq
        rbf = signal**2 * np.exp(-0.5 * sq / length**2)
        K = rbf.copy()
        K[np.diag_indices_from(K)] += noise**2 + 1e-10
        try:
            factor = cho_factor(K, lower=True)
        except np.linalg.LinAlgError:
            return 1e300, np.zeros(3)
        A = cho_solve(factor, self.Y_)
        log_det = 2.0 * np.log(np.diag(factor[0])).sum()
        value = (
            0.5 * float((self.Y_ * A).sum()) + 0.5 * d * log_det + 0.5 * n * d * np.log(2 * np.pi)
        )
        inverse, _ = lapack.dpotri(factor[0], lower=1)
        inverse = np.tril(inverse)
        inner = A @ A.T - d * (inverse + np.tril(inverse, -1).T)
        dK = (rbf * sq / length**2, 2.0 * rbf, 2.0 * noise**2 * np.eye(n))
        return value, np.array([-0.5 * float((inner * g).sum()) for g in dK])


class FirstEditModel(EditModel):
    def _estimator(self, center):
        return FirstSharedGP(self.max_iterations, center=center, method="lbfgs")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    first, second = MOCAP / "cmu_131_01_walk.bvh", MOCAP / "cmu_131_02_walk.bvh"
    cm = leg_length_cm_per_unit(rigmap.rigs.load("biped"), first)
    subject = skeleton_subject(first, cm, "cmu_131")
    clips = [skeleton_clip(subject, first), skeleton_clip(subject, second)]
    config = yaml.safe_load((ROOT / "conf/edit/arms_forward_walking.yaml").read_text())
    edit = Edit.from_config("arms_forward_walking", config, "skeleton")
    segments = [clips[0].frames(280, 830), clips[1].frames(500, 1050)]
    pairs = [(subject.source(s), edit.apply(s, cm)) for s in segments]
    scale = ChannelScale.fit(clips)
    heldout = subject.source(clips[1])
    results, predictions = {}, {}
    for method in ("first", "lbfgs", "profile"):
        kind = FirstEditModel if method == "first" else EditModel
        fits, fit_cpu, rates, rate_cpu = [], [], [], []
        for _ in range(args.repeats):
            start, cpu = time.perf_counter(), time.process_time()
            gp_method = "lbfgs" if method == "first" else method
            model = kind(subject.joints, residual=True, gp_method=gp_method).fit(pairs, scale)
            fits.append(time.perf_counter() - start)
            fit_cpu.append(time.process_time() - cpu)
            start, cpu = time.perf_counter(), time.process_time()
            model.apply(heldout)
            rates.append(heldout.track.n_frames / (time.perf_counter() - start))
            rate_cpu.append(heldout.track.n_frames / (time.process_time() - cpu))
        gps = {"kinematic": model.kinematic_gp_, "acceleration": model.acceleration_gp_}
        predictions[method] = model.predict(heldout)
        results[method] = {
            "refit_s": {"min": min(fits), "all": fits},
            "refit_cpu_s": {"min": min(fit_cpu), "all": fit_cpu},
            "optimum": {name: {"length_scale": gp.length_scale_, "signal": gp.signal_,
                               "noise": gp.noise_, "iterations": gp.iterations_,
                               "log_marginal_likelihood": gp.log_marginal_likelihood_}
                        for name, gp in gps.items()},
            "predict_frames_per_s": {"max": max(rates), "all": rates},
            "predict_frames_per_cpu_s": {"max": max(rate_cpu), "all": rate_cpu},
        }  # fmt: skip
    agreement = {}
    for method in ("lbfgs", "profile"):
        for i, name in enumerate(("kinematic", "acceleration")):
            old, new = predictions["first"][i], predictions[method][i]
            a, b = results["first"]["optimum"][name], results[method]["optimum"][name]
            agreement[f"{method}_vs_first_{name}"] = {
                "log_marginal_likelihood_gain": b["log_marginal_likelihood"]
                - a["log_marginal_likelihood"],
                "hyper_relative_difference": max(
                    abs(b[k] / a[k] - 1) for k in ("length_scale", "signal", "noise")
                ),
                "mean_max_abs_difference_std": float(np.abs(new.mean - old.mean).max()),
                "variance_max_relative_difference": float(
                    np.abs(new.variance / old.variance - 1).max()
                ),
            }
    print(json.dumps({
        "training_frames": sum(s.n_frames for s in segments),
        "kinematic_features": int(heldout.features(subject.joints)[0].shape[1]),
        "channels": len(scale.channels),
        "refit_speedup_vs_first": {
            m: results["first"]["refit_s"]["min"] / results[m]["refit_s"]["min"]
            for m in ("lbfgs", "profile")
        },
        "methods": results,
        "agreement": agreement,
        "predicted_frames": heldout.track.n_frames,
        "real_time_fps": heldout.track.fps,
        "load_average_1min": os.getloadavg()[0],
        "cpus": os.cpu_count(),
    }, indent=2))  # fmt: skip


if __name__ == "__main__":
    main()
