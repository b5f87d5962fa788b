"""Where the edit refit's time goes (002 §7.3): one refit at 2 × 550 CMU frames (the data of
``benchmarks/edits.py``), then, at each GP's optimum, the CPU time of every part of one
marginal-likelihood evaluation (best of 5, one BLAS thread, as the fit runs), the number
of evaluations the L-BFGS-B search made, the Gram matrix's condition number and whether
a float32 Cholesky would do; JSON on stdout.

    PYTHONPATH=src:pipelines .venv/bin/python benchmarks/edits_refit_profile.py
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
from scipy.linalg import blas, cho_factor, cho_solve, lapack
from threadpoolctl import threadpool_limits

from edits import takes_131  # benchmarks/: edits.py's training data
from rigmap.edits.gp import SharedGP
from rigmap.edits.propagation import EditModel


class CountingGP(SharedGP):
    """The default GP, counting its objective evaluations."""

    def _objective(self, theta):
        self.evaluations_ += 1
        return super()._objective(theta)


class CountingModel(EditModel):
    def _estimator(self, center):
        return CountingGP(self.max_iterations, center=center, method=self.gp_method)


def best_ms(call, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        start = time.process_time()
        call()
        times.append(time.process_time() - start)
    return 1e3 * min(times)


def sections(gp: SharedGP) -> dict:
    """CPU ms of each part of :meth:`SharedGP._objective` at the fitted optimum."""
    length, signal, noise = gp.length_scale_, gp.signal_, gp.noise_
    theta = np.log([length, signal, noise])
    sq, (_, d) = gp._sq, gp.Y_.shape
    rbf = signal**2 * np.exp(-0.5 * sq / length**2)
    K = rbf.copy()
    K[np.diag_indices_from(K)] += noise**2 + 1e-10
    factor = cho_factor(K.copy(), lower=True, check_finite=False)
    alpha = cho_solve(factor, gp.Y_, check_finite=False)
    inverse = lapack.dpotri(factor[0].copy(), lower=1)[0]
    inner = blas.dsyrk(1.0, alpha, lower=1)

    def elementwise():
        work = inner - d * inverse
        work *= rbf
        work *= gp._lower
        return np.vdot(work, sq), work.sum()

    out = {
        "rbf_exp": best_ms(lambda: signal**2 * np.exp(-0.5 * sq / length**2)),
        "cholesky": best_ms(lambda: cho_factor(K.copy(), lower=True, check_finite=False)),
        "solve_alpha": best_ms(lambda: cho_solve(factor, gp.Y_, check_finite=False)),
        "potri_inverse": best_ms(lambda: lapack.dpotri(factor[0].copy(), lower=1)),
        "syrk_alpha_alpha_t": best_ms(lambda: blas.dsyrk(1.0, alpha, lower=1)),
        "gradient_elementwise": best_ms(elementwise),
        "whole_objective": best_ms(lambda: gp._objective(theta)),
    }
    low, info = lapack.spotrf(K.astype(np.float32), lower=1)
    single = None
    if info == 0:
        solved = lapack.spotrs(low, gp.Y_.astype(np.float32), lower=1)[0]
        single = float(np.abs(solved - alpha).max() / np.abs(alpha).max())
    return {
        "cpu_ms": out,
        "condition_number": float(np.linalg.cond(K)),
        "float32_cholesky_ok": info == 0,
        "float32_alpha_relative_error": single,
    }


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    subject, _, pairs, scale, _ = takes_131()
    load_before = os.getloadavg()[0]
    start, cpu = time.perf_counter(), time.process_time()
    model = CountingModel(subject.joints, residual=True).fit(pairs, scale)
    refit = {"wall_s": time.perf_counter() - start, "cpu_s": time.process_time() - cpu}
    report = {"refit": refit, "load_average_1min": [load_before, os.getloadavg()[0]]}
    with threadpool_limits(limits=1, user_api="blas"):
        for name in ("kinematic", "acceleration"):
            gp = getattr(model, f"{name}_gp_")
            report[name] = {
                "frames": int(gp.X_.shape[0]),
                "features": int(gp.X_.shape[1]),
                "outputs": int(gp.Y_.shape[1]),
                "evaluations": gp.evaluations_,
                "iterations": gp.iterations_,
                **sections(gp),
            }
    report["cpus"] = os.cpu_count()
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
