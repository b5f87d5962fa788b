"""Edit propagation speed (002 §7.3): refit time at 2 × 550 frames and prediction frames/s; JSON.

The paper: "Estimating the parameters for the Gaussian processes consumes around 30
seconds, and producing frame estimations … proceeds at 2–3 frames per second", with the
training data mirrored (550 frames → 1 100). Here: the skeleton-mode CMU walks, two
550-frame walking stretches (one of each 131 take, 1 100 frames; ``--takes cmu_07``: subject
07's walks, 1 100 frames of three takes, :func:`takes_07`) and the
``arms_forward_walking`` edit; the refit is both GPs (≤ 100 L-BFGS-B iterations each),
fitted several ways in the same run (``--methods``, alternated repeat by repeat):

- ``s28``: the default up to s28, verbatim: the objective through SciPy's ``dpotri``,
  ``dpotrs`` and ``dsyrk`` wrappers, which hold the GIL, so the two fits' threads took
  turns in them;
- ``lbfgs``, the default: the same objective with those three calls made without the
  GIL (:mod:`rigmap.edits.nogil`; bit-identical values, so the same optima);
- ``sequential``: the default's GPs one after the other (one BLAS thread): what the two
  threads buy;
- ``sequential_blas2`` (not run unless asked): one after the other, each on two BLAS
  threads (other rounding: the optima move in the last digits; on the loaded machine one
  such acceleration fit took 95 s wall, 63 s CPU, against 5 s on one thread);
- ``profile``: ℓ searched with σ_f and σ_n profiled out (``rigmap.edits.gp``; another
  optimum, not the default);
- ``first`` (not run unless asked): the first implementation's full-matrix objective.

Each method's optima, and the largest differences of its predictions and propagated clip
from ``s28``'s, are printed; prediction is both GPs plus the banded solve on the whole
second clip (1 247 frames at 120 fps). ``gil_share``: which LAPACK/BLAS calls let the
other thread run (:func:`gil_share`). The machine may be shared: the 1-minute load
average before and after each method, the CPU seconds of this process, of each GP's
fitting thread and of every other process during the refit (``/proc/stat``) are printed
beside the wall-clock seconds.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/edits.py [--repeats 3] [--methods ...]
        [--takes cmu_07]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import yaml
from scipy.linalg import blas, cho_factor, cho_solve, lapack
from threadpoolctl import threadpool_limits

import rigmap.rigs
from rigmap.edits.gp import SharedGP
from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import EditModel
from rigmap.edits.representation import ChannelScale
from rigmap.edits.study import edits_for
from rigmap.edits.subjects import (
    BVH_LEG,
    leg_length_cm_per_unit,
    skeleton_clip,
    skeleton_subject,
)

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
METHODS = ("s28", "lbfgs", "sequential", "sequential_blas2", "profile", "first")
DEFAULT_METHODS = "s28,lbfgs,sequential,profile"


class TimedGP(SharedGP):
    """The default GP, recording its fitting thread's CPU seconds and evaluations."""

    blas_threads = 1

    def fit(self, X, Y, *, initial=None):
        start, self.evaluations_ = time.thread_time(), 0
        with threadpool_limits(limits=self.blas_threads, user_api="blas"):
            self._fit(X, Y, initial)
        self.thread_cpu_s_ = time.thread_time() - start
        return self

    def _objective(self, theta):
        self.evaluations_ += 1
        return super()._objective(theta)


class TwoBlasThreadsGP(TimedGP):
    blas_threads = 2


class S28SharedGP(TimedGP):
    """s28's objective, verbatim: SciPy's ``cho_factor`` / ``cho_solve`` / ``dpotri`` /
    ``dsyrk`` wrappers (the last three hold the GIL), C-ordered work arrays."""

    def _objective(self, theta):
        self.evaluations_ += 1
        with np.errstate(over="ignore"):
            length, signal, noise = np.exp(theta)
            scales = np.array([length**2, signal**2, noise**2])
        if not (np.isfinite(scales).all() and scales[0] > 0):
            return 1e300, np.zeros(3)
        n, d = self.Y_.shape
        sq = self._sq
        work = self.__dict__.get("_work")
        if work is None or work[0].shape != sq.shape:
            work = self._work = (-0.5 * sq, np.empty_like(sq), np.empty_like(sq))
        half_sq, rbf, K = work
        np.divide(half_sq, length**2, out=rbf)
        np.exp(rbf, out=rbf)
        rbf *= signal**2
        np.copyto(K, rbf)
        K[np.diag_indices_from(K)] += noise**2 + 1e-10
        try:
            factor = cho_factor(K, lower=True, overwrite_a=True, check_finite=False)
        except np.linalg.LinAlgError:
            return 1e300, np.zeros(3)
        A = cho_solve(factor, self.Y_, check_finite=False)
        log_det = 2.0 * np.log(np.diag(factor[0])).sum()
        value = (
            0.5 * float((self.Y_ * A).sum()) + 0.5 * d * log_det + 0.5 * n * d * np.log(2 * np.pi)
        )
        inverse, info = lapack.dpotri(factor[0], lower=1, overwrite_c=1)
        if info != 0:
            return 1e300, np.zeros(3)
        inner = blas.dsyrk(1.0, A, lower=1)
        inverse *= d
        inner -= inverse
        trace = float(np.trace(inner))
        inner *= rbf
        inner *= self._lower
        gradient = np.array([
            -0.5 * float(np.vdot(inner, sq)) / length**2,
            -float(inner.sum()),
            -noise**2 * trace,
        ])  # fmt: skip
        return value, gradient


class FirstSharedGP(TimedGP):
    """The first implementation's objective, verbatim: full matrices, ``K⁻¹`` symmetrised."""

    def _objective(self, theta):
        self.evaluations_ += 1
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


GP_CLASSES = {"s28": S28SharedGP, "lbfgs": TimedGP, "sequential": TimedGP,
              "sequential_blas2": TwoBlasThreadsGP, "profile": TimedGP,
              "first": FirstSharedGP}  # fmt: skip


class BenchModel(EditModel):
    """:class:`EditModel` with the benchmark's GP class and thread arrangement."""

    def __init__(self, *args, method: str, **kwargs):
        super().__init__(*args, gp_method="profile" if method == "profile" else "lbfgs", **kwargs)
        self.gp_class = GP_CLASSES[method]
        self.fit_threads = 1 if method.startswith("sequential") else 2

    def _estimator(self, center):
        return self.gp_class(self.max_iterations, center=center, method=self.gp_method)


def busy_cpu_s() -> float:
    """CPU seconds every process of the machine has used since boot (``/proc/stat``)."""
    with open("/proc/stat") as stat:
        fields = [int(v) for v in stat.readline().split()[1:]]
    user, nice, system, _, _, irq, softirq = fields[:7]
    return (user + nice + system + irq + softirq) / os.sysconf("SC_CLK_TCK")


def gil_share(n: int = 2000, outputs: int = 98) -> dict:
    """Which LAPACK/BLAS calls of the objective let other Python threads run: while this
    thread makes one call on an ``n × n`` SPD matrix (synthetic, seeded; large so each call
    lasts long against the interpreter's 5 ms switch interval), another thread counts in a
    pure-Python loop; its count during the call over its count during an equally long
    sleep right after is the share of the call's time other Python code could run: near 0
    for a call that holds the GIL; for one that releases it about 1 with a core to spare,
    lower on a loaded machine (one BLAS thread)."""
    import threading

    from rigmap.edits import nogil

    rng = np.random.default_rng(0)
    M = rng.normal(size=(n, n))
    K = np.asfortranarray(M @ M.T + n * np.eye(n))
    factor = lapack.dpotrf(K, lower=1)[0]
    Y = rng.normal(size=(n, outputs))
    A = np.asfortranarray(Y)
    calls = {
        "scipy_dpotrf": lambda: lapack.dpotrf(K, lower=1),
        "scipy_dpotri": lambda: lapack.dpotri(factor, lower=1),
        "scipy_dpotrs": lambda: lapack.dpotrs(factor, Y, lower=1),
        "scipy_dsyrk": lambda: blas.dsyrk(1.0, A, lower=1),
        "nogil_potri": lambda: nogil.potri_lower(factor.copy(order="F")),
        "nogil_potrs": lambda: nogil.potrs_lower(factor, Y),
        "nogil_syrk": lambda: nogil.syrk_lower(A),
    }
    count, stop = [0], threading.Event()

    def spin():
        while not stop.is_set():
            count[0] += 1

    out = {}
    with threadpool_limits(limits=1, user_api="blas"):
        spinner = threading.Thread(target=spin)
        spinner.start()
        for name, call in calls.items():
            before, start = count[0], time.perf_counter()
            call()
            wall, during = time.perf_counter() - start, count[0] - before
            before = count[0]
            time.sleep(wall)
            out[name] = {"other_thread_share": during / max(count[0] - before, 1),
                         "call_ms": 1e3 * wall}  # fmt: skip
        stop.set()
        spinner.join()
    return out


def takes_131():
    """Two 550-frame walking stretches, one of each 131 take; the second take predicted."""
    first, second = MOCAP / "cmu_131_01_walk.bvh", MOCAP / "cmu_131_02_walk.bvh"
    cm = leg_length_cm_per_unit(rigmap.rigs.load("biped"), first)
    subject = skeleton_subject(first, cm, "cmu_131")
    clips = [skeleton_clip(subject, first), skeleton_clip(subject, second)]
    config = yaml.safe_load((ROOT / "conf/edit/arms_forward_walking.yaml").read_text())
    edit = Edit.from_config("arms_forward_walking", config, "skeleton")
    segments = [clips[0].frames(280, 830), clips[1].frames(500, 1050)]
    pairs = [(subject.source(s), edit.apply(s, cm)) for s in segments]
    return subject, segments, pairs, ChannelScale.fit(clips), subject.source(clips[1])


def takes_07():
    """Subject 07's walks as the edits stage reads them (conf/edits/default.yaml, cmu_07:
    the other conversion's joint names): no take holds 550 frames, so the slow walks 07_05
    and 07_04 whole and 07_06's first frames make the same 1 100; 07_01 (1.34 m/s) predicted."""
    settings = yaml.safe_load((ROOT / "conf/edits/default.yaml").read_text())
    spec = settings["subjects"]["cmu_07"]
    reference = str(ROOT / spec["reference"])
    aliases = spec["joint_aliases"]
    leg = tuple(aliases.get(joint, joint) for joint in BVH_LEG)
    cm = leg_length_cm_per_unit(rigmap.rigs.load("biped"), reference, bvh_leg=leg)
    subject = skeleton_subject(reference, cm, "cmu_07", tuple(spec["heading_joints"]))
    config = yaml.safe_load((ROOT / "conf/edit/arms_forward_walking.yaml").read_text())
    catalogue = {"arms_forward_walking": config}
    edit = edits_for(catalogue, ["arms_forward_walking"], "skeleton", spec, "cmu_07")
    edit = edit["arms_forward_walking"]
    clips = [skeleton_clip(subject, MOCAP / f"cmu_07_{n}.bvh") for n in ("05", "04", "06")]
    segments, left = [], 1100
    for clip in clips:
        take = min(left, clip.n_frames)
        segments.append(clip.frames(0, take))
        left -= take
        if not left:
            break
    pairs = [(subject.source(s), edit.apply(s, cm, subject.skeleton)) for s in segments]
    heldout = subject.source(skeleton_clip(subject, MOCAP / "cmu_07_01.bvh"))
    return subject, segments, pairs, ChannelScale.fit(clips), heldout


TAKES = {"cmu_131": takes_131, "cmu_07": takes_07}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--takes", choices=sorted(TAKES), default="cmu_131",
                        help="the real takes learned from and predicted on")  # fmt: skip
    parser.add_argument("--methods", default=DEFAULT_METHODS,
                        help=f"comma-separated, from {', '.join(METHODS)}; s28 first")  # fmt: skip
    args = parser.parse_args()
    methods = args.methods.split(",")
    if methods[0] != "s28" or not set(methods) <= set(METHODS):
        parser.error(f"--methods: s28 first, then any of {METHODS}")
    subject, segments, pairs, scale, heldout = TAKES[args.takes]()
    runs = {m: {"refit_s": [], "refit_cpu_s": [], "others_cpu_s": [], "load_1min": [],
                "thread_cpu_s": {"kinematic": [], "acceleration": []},
                "predict_frames_per_s": [], "predict_frames_per_cpu_s": []}
            for m in methods}  # fmt: skip
    models = {}
    for _ in range(args.repeats):
        for method in methods:  # alternated, so a change of load hits every method alike
            run = runs[method]
            load = os.getloadavg()[0]
            start, cpu, busy = time.perf_counter(), time.process_time(), busy_cpu_s()
            model = BenchModel(subject.joints, residual=True, method=method).fit(pairs, scale)
            wall, cpu = time.perf_counter() - start, time.process_time() - cpu
            run["refit_s"].append(wall)
            run["refit_cpu_s"].append(cpu)
            run["others_cpu_s"].append(max(busy_cpu_s() - busy - cpu, 0.0))
            run["load_1min"].append([load, os.getloadavg()[0]])
            for name in ("kinematic", "acceleration"):
                gp = getattr(model, f"{name}_gp_")
                run["thread_cpu_s"][name].append(gp.thread_cpu_s_)
            start, cpu = time.perf_counter(), time.process_time()
            model.apply(heldout)
            run["predict_frames_per_s"].append(
                heldout.track.n_frames / (time.perf_counter() - start)
            )
            run["predict_frames_per_cpu_s"].append(
                heldout.track.n_frames / (time.process_time() - cpu)
            )
            models[method] = model
    results, reference = {}, models["s28"]
    reference_predictions = reference.predict(heldout)
    reference_clip = reference.apply(heldout).values
    for method in methods:
        model, run = models[method], runs[method]
        gps = {"kinematic": model.kinematic_gp_, "acceleration": model.acceleration_gp_}
        predictions = model.predict(heldout)
        agreement = {
            name: {
                "same_optimum": all(
                    getattr(gp, k) == getattr(getattr(reference, f"{name}_gp_"), k)
                    for k in ("length_scale_", "signal_", "noise_")
                ),
                "mean_max_abs_difference_std": float(
                    np.abs(new.mean - old.mean).max()
                ),
                "variance_max_relative_difference": float(
                    np.abs(new.variance / old.variance - 1).max()
                ),
            }
            for (name, gp), new, old in zip(gps.items(), predictions, reference_predictions,
                                            strict=True)
        }  # fmt: skip
        agreement["propagated_clip_max_abs_difference"] = float(
            np.abs(model.apply(heldout).values - reference_clip).max()
        )
        results[method] = {
            **{k: v for k, v in run.items() if k != "thread_cpu_s"},
            "refit_s_min": min(run["refit_s"]),
            "refit_cpu_s_min": min(run["refit_cpu_s"]),
            "thread_cpu_s": run["thread_cpu_s"],
            "predict_frames_per_s_max": max(run["predict_frames_per_s"]),
            "optimum": {name: {"length_scale": gp.length_scale_, "signal": gp.signal_,
                               "noise": gp.noise_, "iterations": gp.iterations_,
                               "evaluations": gp.evaluations_,
                               "log_marginal_likelihood": gp.log_marginal_likelihood_}
                        for name, gp in gps.items()},
            "vs_s28": agreement,
        }  # fmt: skip
    print(json.dumps({
        "takes": args.takes,
        "training": [s.source for s in segments],
        "heldout": heldout.track.source,
        "training_frames": sum(s.n_frames for s in segments),
        "kinematic_features": int(heldout.features(subject.joints)[0].shape[1]),
        "channels": len(scale.channels),
        "repeats": args.repeats,
        "refit_speedup_vs_s28": {
            m: results["s28"]["refit_s_min"] / results[m]["refit_s_min"] for m in methods
        },
        "methods": results,
        "gil_share": gil_share(),
        "predicted_frames": heldout.track.n_frames,
        "real_time_fps": heldout.track.fps,
        "cpus": os.cpu_count(),
    }, indent=2))  # fmt: skip


if __name__ == "__main__":
    main()
