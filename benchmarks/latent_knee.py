"""Is there a knee at 3 latent dimensions (Bailey et al. 2016, §6)? Prints JSON.

The paper chose 3 latent dimensions because models of 3 or more gave perceptually
similar animation (§6); issue #18 asks for held-out reconstruction against the latent
dimension 1–5 to show that knee. This script measures, per label of the face's
expression library, held-out takes projected into the model (Eq 15, Levenberg–Marquardt
from the nearest training point) and mapped back (Eq 8 → PCA → unscale → clamp), as the
``latent_evaluate`` stage does, on all mesh vertices (cm, RMS of per-vertex distances),
next to what the data itself allows:

- the label's PCA spectrum (components at 85, 95, 99 % of the scaled variance) and the
  held-out error of PCA alone at 1, 2, 3, 4, 5, 8 and 16 components (a linear model of
  that size, and the floor under a GPLVM on 8 PCA components);
- the knee (ours, :func:`rigmap.latent.measures.knee_dimension`): the smallest latent
  dimension that has made 90 % of the error's drop from the smallest dimension swept to
  the largest (scale-free: the errors of a label with few degrees of freedom fall to
  near zero, where "within x % of the largest's error" would only measure fit noise).

``--coordinated`` builds the takes another way (:mod:`rigmap.animation.library.
face_expressions`): ``none`` is the library's (every key pose draws its own slider
intensities, asymmetry, mouth shift and jaw swing); ``k`` (0–3) draws ``k`` numbers
per take (intensity, asymmetry, mouth shift) that every key pose uses — one expression
played with a few coordinated controls, plus timing. ``talk`` keeps its own draws, so it
is left out of coordinated runs.

Metrics are rigmap's own (the paper reports none). Fit seconds are wall-clock on a
shared machine; the load average is printed with them.

    .venv/bin/python benchmarks/latent_knee.py [--size quick|paper] [--labels happy roar]
        [--coordinated none 1 2 3] [--dims 1 2 3 4 5] [--max-iter 100]
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from rigmap.latent import GPLVMSettings
from rigmap.latent.control_scaling import fit_control_scaling
from rigmap.latent.library import face_expression_sets
from rigmap.latent.measures import KNEE_DROP, knee_dimension, latent_dim_sweep, surface_rms_cm
from rigmap.latent.pca import fit_pca
from rigmap.rigs import load

PCA_SIZES = (1, 2, 3, 4, 5, 8, 16)


def pca_rows(rig, P, P_test) -> tuple[dict, dict]:
    """Components at 85/95/99 % of the scaled variance, and PCA-alone held-out error."""
    scaling = fit_control_scaling(rig, P)
    Z, Z_test = scaling.scale(P), scaling.scale(P_test)
    full = fit_pca(Z, n_components=min(len(P), P.shape[1]))
    cumulative = np.cumsum(full.explained_variance_ratio_)
    at = {f"{v:g}": int(np.searchsorted(cumulative, v) + 1) for v in (0.85, 0.95, 0.99)}
    floor = {}
    for k in PCA_SIZES:
        pca = fit_pca(Z, n_components=min(k, len(P), P.shape[1]))
        back = scaling.unscale(pca.inverse_transform(pca.transform(Z_test)))
        floor[str(k)] = surface_rms_cm(rig, P_test, back)
    return at, floor


def measure(rig, args, coordinated) -> list[dict]:
    labels = args.labels
    if coordinated is not None:
        labels = [label for label in labels if label != "talk"]
    kw = {"size": args.size, "labels": labels, "coordinated": coordinated, "seed": args.seed}
    sets = face_expression_sets(rig, **kw)
    heldout = face_expression_sets(rig, heldout=True, **kw)
    settings = GPLVMSettings(max_iter=args.max_iter)
    rows = []
    for label in labels:
        P, P_test = sets[label].values, heldout[label].values
        at, floor = pca_rows(rig, P, P_test)
        sweep = latent_dim_sweep(
            rig, sets, heldout, [label], args.dims, settings=settings, fps=24.0,
            variance=(0.85, args.n_pca),
        )  # fmt: skip
        errors = {r["latent_dim"]: r["surface_rms_cm"] for r in sweep}
        rows.append(
            {
                "label": label,
                "frames": sets[label].n_frames,
                "heldout_frames": heldout[label].n_frames,
                "pca_components_at": at,
                "pca_alone_heldout_rms_cm": floor,
                "gplvm_heldout_rms_cm": {str(q): e for q, e in errors.items()},
                "gplvm_controls_rms": {str(r["latent_dim"]): r["controls_rms"] for r in sweep},
                "knee": knee_dimension(errors),
                "fit_s": {str(r["latent_dim"]): round(r["fit_s"], 2) for r in sweep},
            }
        )
        print(f"{coordinated} {label}: knee {rows[-1]['knee']}", file=sys.stderr, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", default="quick", choices=["quick", "paper"])
    parser.add_argument("--labels", nargs="+", default=["happy", "grumpy", "bored", "roar"])
    parser.add_argument("--coordinated", nargs="+", default=["none", "1", "2", "3"])
    parser.add_argument("--dims", nargs="+", type=int, default=[1, 2, 3, 4, 5])
    parser.add_argument("--max-iter", type=int, default=100)
    parser.add_argument("--n-pca", type=int, default=8)  # the stages' latent.n_pca
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rig = load("face")
    runs = {}
    for value in args.coordinated:
        coordinated = None if value == "none" else int(value)
        rows = measure(rig, args, coordinated)
        runs[value] = {
            "labels": rows,
            "knees": [r["knee"] for r in rows],
            "gplvm_heldout_rms_cm_mean": {
                str(q): float(np.mean([r["gplvm_heldout_rms_cm"][str(q)] for r in rows]))
                for q in args.dims
            },
        }
    print(
        json.dumps(
            {
                "benchmark": "latent_knee",
                "metrics_are_rigmaps_own": True,
                "size": args.size,
                "max_iter": args.max_iter,
                "n_pca": args.n_pca,
                "knee_drop": KNEE_DROP,
                "load_average": os.getloadavg(),
                "runs": runs,
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
