"""Latent synthesis on the face's expression library (Bailey et al. 2016 §5–6); prints JSON.

``--rig arkit_face``: on the ARKit face from the shared Live Link Face takes instead (issue
#41: its mesh evaluated each frame from the captured curves' models).

One latent model per label of the quick library (8 labels × 3 takes, ~150 frames a
label; scaling → PCA (8 components, ours: scaled face controls reach 85 % with 1–3
because the jaw moves the most vertices) → 3-D GPLVM), then:

- **fit**: seconds, frames and L-BFGS iterations per model;
- **matching points** per model pair (both directions merged): how many, their spread
  in the source latent space, and the match distance (largest vertex distance of the
  two poses, cm), with the threshold;
- **controller speed**: a looping script of MOVE / IDLE / TRANSITION / PLAY commands,
  the face's whole mesh (3 362 vertices) evaluated from each frame's controls as a
  renderer would; sustained frames/s (frames over wall time) and the p50/p99 frame
  time (step + mesh) in ms, wall-clock and the thread's CPU time (the part the
  machine's load does not add), torch on 1 thread of the 2 cores (ours: one pose is too
  small to split; on a loaded machine a second thread made the mesh 11–17 ms instead
  of 1 ms) (goal ≥ 240 fps);
- **transition smoothness** on every ordered pair: ours (TRANSITION from a seeded
  training frame of the source, 12-frame blend) against the motion graph's lowest-
  distance transition between the two sets' takes (Kovar; 12-frame window and blend).
  Peak vertex acceleration and jerk (per frame, the largest over vertices; finite
  differences at 24 fps, cm/s² and cm/s³) in the frames around the switch (12 before
  the blend to 12 after it), divided by the 95th percentile of the same per-frame
  value over the two sets' training takes. Also the fraction of source frames a
  transition can start from: ours measured by running TRANSITION from sampled frames
  (success rate), the graph's the share of source frames that carry a transition
  below a threshold (per-frame RMS vertex distance over the window, ours: 0.1, 0.2 and
  0.4 cm; Kovar leaves the threshold to the user).

Metrics are rigmap's own (the paper reports none); wall-clock on a shared machine,
load average printed.

    .venv/bin/python benchmarks/synthesis.py [--frames 2400] [--labels happy roar …]
        [--cache models/] [--skip-transitions]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch

from rigmap.animation.library.face_expressions import LABELS
from rigmap.latent import files
from rigmap.latent.captured_sets import captured_sets
from rigmap.latent.library import face_expression_sets, fit_models
from rigmap.latent.motion_graph import (
    WINDOW,
    blend_transition,
    find_transitions,
    surface_features,
)
from rigmap.latent.segment_labels import read_labels
from rigmap.latent.synthesis import Controller, Idle, Move, Play, Transition
from rigmap.latent.transitions import MATCH_THRESHOLD_CM, match_models
from rigmap.rigs import load

FPS = 24.0  # the face library's; --rig arkit_face plays the captured takes' 30 fps
ROOT = Path(__file__).resolve().parents[1]
CAPTURED_LABELS = ROOT / "conf" / "latent" / "labels" / "shared_face.yaml"
CAPTURED_FPS, CAPTURED_THRESHOLD_CM = 30.0, 0.2  # conf/latent/default.yaml's arkit_face_*
GRAPH_THRESHOLDS_CM = (0.1, 0.2, 0.4)  # ours: per-frame RMS vertex distance over a window


def per_frame_peaks(rig, P, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the largest vertex acceleration (cm/s²) and jerk (cm/s³)."""
    V = np.asarray(rig.mesh(rig.expand_used(P)))
    acc = np.linalg.norm(np.diff(V, 2, axis=0), axis=-1).max(-1) * fps**2
    jerk = np.linalg.norm(np.diff(V, 3, axis=0), axis=-1).max(-1) * fps**3
    return acc, jerk


def training_p95(peaks, labels) -> tuple[float, float]:
    """95th percentiles of the per-frame peaks over the labels' training takes."""
    acc = np.concatenate([a for label in labels for a, _ in peaks[label]])
    jerk = np.concatenate([j for label in labels for _, j in peaks[label]])
    return float(np.percentile(acc, 95)), float(np.percentile(jerk, 95))


def window_peaks(rig, P, start: int, blend: int, fps: float) -> tuple[float, float]:
    lo, hi = max(0, start - blend), min(len(P), start + 2 * blend + 3)
    acc, jerk = per_frame_peaks(rig, P[lo:hi], fps)
    return float(acc.max()), float(jerk.max())


def speed_script(rng, fitted, labels, n: int):
    """A looping command script (names only valid for the model each runs in)."""
    model = labels[0]
    commands = []
    for k in range(n):
        kind = k % 4
        names = fitted.sets[model].names
        if kind == 0:
            take = names[int(rng.integers(len(names)))]
            frame = int(rng.integers(len(fitted.sets[model].take(take))))
            commands.append(Move(take=take, frame=frame, path="graph" if k % 8 == 0 else "line"))
        elif kind == 1:
            commands.append(Idle(int(rng.integers(12, 48))))
        elif kind == 2:
            model = labels[int(rng.integers(len(labels)))]
            commands.append(Transition(model))
        else:
            names = fitted.sets[model].names
            commands.append(Play(names[int(rng.integers(len(names)))]))
    return commands


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=2400)
    parser.add_argument(
        "--rig",
        choices=("face", "arkit_face"),
        default="face",
        help="face: its keyed expression library; arkit_face: the shared Live Link Face takes "
        "as conf/latent/labels/shared_face.yaml labels them, at their 30 fps, matched at the "
        "rig's 0.2 cm (conf/latent/default.yaml)",
    )
    parser.add_argument("--labels", nargs="*", default=None, help="default: all of the rig's")
    parser.add_argument("--n-pca", type=int, default=8)
    parser.add_argument("--starts", type=int, default=4, help="TRANSITION starts per pair")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch threads (1: a one-pose mesh is too small "
        "to split, and a second thread waits on a shared machine: 1 ms → 11–17 ms measured)",
    )
    parser.add_argument(
        "--cache", help="folder of the fitted models to reuse (fit once; arrays + JSON)"
    )
    parser.add_argument("--skip-transitions", action="store_true")
    args = parser.parse_args(argv)
    if (
        args.rig == "arkit_face" and not args.skip_transitions
    ):  # measured: it stops in find_transitions
        parser.error(
            "--rig arkit_face needs --skip-transitions: some captured takes are shorter than the "
            "motion graph's 12-frame window (its smoothness is latent_evaluate's, in the pipeline)"
        )
    torch.set_num_threads(args.threads)
    rig = load(args.rig)
    if args.rig == "arkit_face":
        fps, threshold = CAPTURED_FPS, CAPTURED_THRESHOLD_CM
        labels = list(args.labels or read_labels(CAPTURED_LABELS).labels)
    else:
        fps, threshold = FPS, MATCH_THRESHOLD_CM
        labels = list(args.labels or LABELS)
    out: dict = {"load_average": [round(x, 2) for x in os.getloadavg()], "labels": labels}
    out["rig"], out["mesh_vertices"] = rig.name, rig.n_vertices

    key = {"rig": rig.name, "labels": labels, "n_pca": args.n_pca, "seed": args.seed}
    key_file = os.path.join(args.cache or "", "key.json")
    cached = None
    if args.cache and os.path.exists(key_file):
        with open(key_file) as f:
            if json.load(f) == key:
                cached = files.load_fitted(args.cache)  # arrays + JSON, never unpickled
    if cached is None:
        if args.rig == "arkit_face":
            sets = captured_sets(rig, CAPTURED_LABELS, fps=fps, labels=labels)
        else:
            sets = face_expression_sets(rig, labels=labels, seed=args.seed)
        fitted = fit_models(rig, sets, fps=fps, n_pca=args.n_pca)
    else:
        sets, fitted = cached.sets, cached
        out["fit_from_cache"] = args.cache
    out["fit"] = {
        label: {
            "frames": sets[label].n_frames,
            "takes": len(sets[label].names),
            "pca_dims": int(m.pca.n_components_),
            "seconds": round(fitted.fit_seconds[label], 2),
            "lbfgs_iterations": m.gplvm.iterations,
        }
        for label, m in fitted.models.items()
    }
    out["fit_seconds_total"] = round(sum(fitted.fit_seconds.values()), 1)

    start = time.perf_counter()
    table = match_models(rig, fitted.models, threshold_cm=threshold)
    match_seconds = time.perf_counter() - start
    if args.cache and cached is None:
        files.save_fitted(args.cache, fitted)
        with open(key_file, "w") as f:
            json.dump(key, f)
    pairs = {}
    for a, b in itertools.combinations(labels, 2):
        m = table.pair(a, b)
        pairs[f"{a}-{b}"] = {
            "points": len(m),
            "spread_latent": round(m.spread(), 3),
            "distance_cm_median": round(float(np.median(m.distance_cm)), 4) if len(m) else None,
            "distance_cm_min": round(float(m.distance_cm.min()), 4) if len(m) else None,
        }
    counts = [p["points"] for p in pairs.values()]
    out["matching"] = {
        "threshold_cm": table.threshold_cm,
        "seconds": round(match_seconds, 2),
        "points_min": int(min(counts)),
        "points_median": float(np.median(counts)),
        "points_max": int(max(counts)),
        "pairs_without_points": [k for k, p in pairs.items() if p["points"] == 0],
        "pairs": pairs,
    }

    # --- controller speed with the mesh every frame ------------------------------------
    rng = np.random.default_rng(args.seed)
    ctrl = Controller(fitted.models, start=labels[0], takes=sets, transitions=table, seed=args.seed)
    script = iter(speed_script(rng, fitted, labels, 10_000))
    times = np.zeros(args.frames)
    cpu_times = np.zeros(args.frames)  # this thread's CPU time: what the load does not add
    mesh_times = np.zeros(args.frames)
    for _ in range(48):  # warm-up
        rig.mesh(rig.expand_used(ctrl.step()[None]))
    wall = time.perf_counter()
    for k in range(args.frames):
        t0, c0 = time.perf_counter(), time.thread_time()
        if not ctrl.busy:
            ctrl.submit(next(script))
        controls = ctrl.step()
        t1 = time.perf_counter()
        rig.mesh(rig.expand_used(controls[None]))
        t2 = time.perf_counter()
        times[k], mesh_times[k] = t2 - t0, t2 - t1
        cpu_times[k] = time.thread_time() - c0
    wall = time.perf_counter() - wall
    kinds = {}
    for entry in ctrl.log:
        name = type(entry.command).__name__.upper()
        rec = kinds.setdefault(name, {"count": 0, "success": 0, "frames": []})
        rec["count"] += 1
        rec["success"] += int(entry.success)
        rec["frames"].append(entry.frames)
    out["controller"] = {
        "frames": args.frames,
        "torch_threads": torch.get_num_threads(),
        "fps_sustained": round(args.frames / wall, 1),
        "frame_ms_p50": round(1e3 * float(np.percentile(times, 50)), 3),
        "frame_ms_p99": round(1e3 * float(np.percentile(times, 99)), 3),
        "frame_ms_max": round(1e3 * float(times.max()), 3),
        "frame_cpu_ms_p50": round(1e3 * float(np.percentile(cpu_times, 50)), 3),
        "frame_cpu_ms_p99": round(1e3 * float(np.percentile(cpu_times, 99)), 3),
        "mesh_ms_p50": round(1e3 * float(np.percentile(mesh_times, 50)), 3),
        "commands": {
            k: {
                "count": v["count"],
                "success_rate": round(v["success"] / v["count"], 3),
                "frames_median": float(np.median(v["frames"])),
            }
            for k, v in kinds.items()
        },
    }

    if args.skip_transitions:
        json.dump(out, sys.stdout, indent=1)
        print()
        return
    # --- transition smoothness: ours against the motion graph --------------------------
    features = {
        label: {n: surface_features(rig, v) for n, v in zip(s.names, s.takes, strict=True)}
        for label, s in sets.items()
    }
    n_vertices = rig.n_vertices
    peaks = {label: [per_frame_peaks(rig, t, fps) for t in s.takes] for label, s in sets.items()}
    records = {}
    for a, b in itertools.permutations(labels, 2):
        p95_acc, p95_jerk = training_p95(peaks, (a, b))
        ours_acc, ours_jerk, successes = [], [], 0
        for s in range(args.starts):
            r = np.random.default_rng([args.seed, s, labels.index(a), labels.index(b)])
            take = sets[a].names[int(r.integers(len(sets[a].names)))]
            frame = int(r.integers(len(sets[a].take(take))))
            c = Controller(
                fitted.models, start=a, takes=sets, transitions=table, seed=s,
                start_point=fitted.models[a].latent[sets[a].rows(take)[frame]],
            )  # fmt: skip
            P = c.run([Transition(b, idle_frames=2 * WINDOW)])
            entry = c.log[-1]
            successes += int(entry.success)
            for switch in entry.switches:
                acc, jerk = window_peaks(rig, P, switch, c.settings.blend_frames, fps)
                ours_acc.append(acc / p95_acc)
                ours_jerk.append(jerk / p95_jerk)
        found = find_transitions(features[a], features[b], threshold=np.inf)
        source_frames = sum(len(v) for v in sets[a].takes)
        rec = {
            "ours_peak_acc_rel_p95": round(float(np.max(ours_acc)), 3) if ours_acc else None,
            "ours_peak_jerk_rel_p95": round(float(np.max(ours_jerk)), 3) if ours_jerk else None,
            "ours_start_success": round(successes / args.starts, 3),
        }
        for cm in GRAPH_THRESHOLDS_CM:
            limit = WINDOW * n_vertices * cm**2
            starts = {(t.source, t.i) for t in found if t.distance <= limit}
            rec[f"graph_start_fraction_{cm}cm"] = round(len(starts) / source_frames, 3)
        if found:
            best = found[0]
            P, at = blend_transition(
                sets[a].take(best.source), sets[b].take(best.target), best.i, best.j
            )
            acc, jerk = window_peaks(rig, P, at, WINDOW, fps)
            rec.update(
                graph_peak_acc_rel_p95=round(acc / p95_acc, 3),
                graph_peak_jerk_rel_p95=round(jerk / p95_jerk, 3),
                graph_best_rms_cm=round(float(np.sqrt(best.distance / (WINDOW * n_vertices))), 4),
            )
        records[f"{a}->{b}"] = rec

    def summary(key):
        values = [r[key] for r in records.values() if r.get(key) is not None]
        return {"median": float(np.median(values)), "max": float(np.max(values))}

    out["transitions"] = {
        "summary": {
            key: summary(key)
            for key in (
                "ours_peak_acc_rel_p95",
                "graph_peak_acc_rel_p95",
                "ours_peak_jerk_rel_p95",
                "graph_peak_jerk_rel_p95",
                "ours_start_success",
                *(f"graph_start_fraction_{cm}cm" for cm in GRAPH_THRESHOLDS_CM),
            )
        },
        "pairs": records,
    }
    json.dump(out, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
