"""Rig evaluation speed: poses/s at several batch sizes, Jacobians/s by FD and autodiff.

Prints one JSON document. The paper's Maya rig needed about an hour for
100 000 poses (§5.2); the issue asks for under 10 s for the quadruped here.
Usage: python benchmarks/rig_eval.py [--rigs quadruped biped] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import platform
import time

import numpy as np
import torch

from rigmap.refine import jacobian
from rigmap.rigs import available, load

IN_PROCESS_RIGS = ("quadruped", "biped", "face", "squirrel")


def random_controls(rig, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    used = rig.controls.used_indices
    Y = rig.default_controls(n)
    lo, hi = rig.controls.lower[used], rig.controls.upper[used]
    Y[:, used] += 0.3 * (rng.uniform(lo, hi, size=(n, len(used))) - Y[:, used])
    return Y


def best_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def measure(rig, repeats: int, big_batch: int) -> dict:
    result: dict = {
        "joints": rig.n_joints,
        "controls": rig.n_controls,
        "used_controls": len(rig.used_controls),
    }
    # mesh rigs return every vertex: 100 000 squirrel poses would be 2.7 GB of output alone
    big_batch = big_batch if rig.n_joints <= 500 else min(big_batch, 10_000)
    for batch in (1, 1000, big_batch):
        Y = random_controls(rig, batch)
        rig.evaluate(Y[: min(batch, 8)])  # warm-up
        seconds = best_time(lambda Y=Y: rig.evaluate(Y), 1 if batch == big_batch else repeats)
        result[f"batch_{batch}"] = {"seconds": seconds, "poses_per_s": batch / seconds}
    Y = random_controls(rig, 64, seed=1)
    for method in ("finite_difference", "autodiff"):
        if method == "autodiff" and not rig.differentiable:
            continue
        jacobian(rig, Y[:2], method=method)  # warm-up
        seconds = best_time(lambda method=method: jacobian(rig, Y, method=method), 1)
        result[f"jacobian_{method}"] = {
            "batch": len(Y),
            "seconds": seconds,
            "jacobians_per_s": len(Y) / seconds,
        }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="*", default=None, help="default: every in-process rig")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--big-batch", type=int, default=100_000)
    args = parser.parse_args()
    names = args.rigs or [n for n in IN_PROCESS_RIGS if n in available()]
    report = {
        "machine": {
            "cpus": torch.get_num_threads(),
            "python": platform.python_version(),
            "torch": torch.__version__,
        },
        "unit": "poses/s and Jacobians/s, best of --repeats (one run for the big batch)",
        "rigs": {},
    }
    for name in names:
        try:
            rig = load(name)
        except Exception as error:
            report["rigs"][name] = {"error": f"{type(error).__name__}: {error}"}
            continue
        report["rigs"][name] = measure(rig, args.repeats, args.big_batch)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
