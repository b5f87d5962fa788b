"""GPLVM fit time against training frames (Bailey et al. 2016, §7); prints JSON.

§7: "the computation time required to train the model grows cubically with the size of
the training data". Training sets of 100, 200, 400 and 800 frames (the paper's labels
hold 100–800) are whole takes of the face's paper-size expression library, label after
label (the last take cut to reach the size), scaled → 8 PCA components (the stages'
``latent.n_pca``) → a 3-D GPLVM with both priors, L-BFGS capped at ``--max-iter``
iterations (the same cap at every size, so seconds per objective evaluation — one
Cholesky of the ``N × N`` kernel, the connectivity prior's ``N × N`` matrix exponential
and their gradients — is the comparable number). Timed: the GPLVM's fit alone (scaling
and PCA done before), after one warm-up fit, median of ``--repeats``. Reported per
size: fit seconds, objective evaluations, L-BFGS iterations, seconds per evaluation,
and the log-log slope of seconds per evaluation between consecutive sizes (3 for a
cubic cost).

Wall-clock seconds on a shared machine: the load average is printed with them.

    .venv/bin/python benchmarks/latent_fit_time.py [--frames 100 200 400 800] [--max-iter 30]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

from rigmap.latent import GPLVM, GPLVMSettings, fit_control_scaling, fit_pca
from rigmap.latent.library import face_expression_sets
from rigmap.latent.model import segment_times
from rigmap.rigs import load


def training_set(sets, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``n`` frames of whole takes, label after label (segments = take names)."""
    values, segments, total = [], [], 0
    for entry in sets.values():
        for name, take in zip(entry.names, entry.takes, strict=True):
            keep = take[: n - total]
            values.append(keep)
            segments += [name] * len(keep)
            total += len(keep)
            if total == n:
                return np.vstack(values), np.array(segments, dtype=object)
    raise SystemExit(f"the library holds {total} frames, fewer than {n}")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[100, 200, 400, 800])
    parser.add_argument("--max-iter", type=int, default=30)
    parser.add_argument("--n-pca", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    rig = load("face")
    sets = face_expression_sets(rig, size="paper")
    settings = GPLVMSettings(max_iter=args.max_iter)

    def fit(n: int) -> tuple[float, GPLVM, int]:
        P, segments = training_set(sets, n)
        Z = fit_control_scaling(rig, P).scale(P)
        Y = fit_pca(Z, n_components=args.n_pca).transform(Z)
        started = time.perf_counter()
        g = GPLVM(settings).fit(Y, segments, segment_times(segments, 24.0))
        return time.perf_counter() - started, g, len(set(segments))

    fit(min(args.frames))  # warm-up: torch's first calls
    rows = []
    for n in args.frames:
        runs = [fit(n) for _ in range(args.repeats)]
        seconds = float(np.median([r[0] for r in runs]))
        _, g, n_segments = runs[0]
        row = {
            "frames": n,
            "segments": n_segments,
            "fit_s": round(seconds, 3),
            "fit_s_runs": [round(r[0], 3) for r in runs],
            "objective_evaluations": len(g.history),
            "lbfgs_iterations": g.iterations,
            "s_per_evaluation": seconds / max(1, len(g.history)),
            "load_average": round(os.getloadavg()[0], 2),
        }
        if rows:
            prev = rows[-1]
            row["slope_vs_previous"] = round(
                math.log(row["s_per_evaluation"] / prev["s_per_evaluation"])
                / math.log(n / prev["frames"]),
                2,
            )
        rows.append(row)
        print(json.dumps(row), file=sys.stderr, flush=True)
    out = {"benchmark": "latent_fit_time", "max_iter": args.max_iter, "n_pca": args.n_pca,
           "latent_dim": 3, "rows": rows}  # fmt: skip
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
