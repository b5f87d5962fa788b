"""The measurements of latent synthesis (issue #18's "must show"), rigmap's own.

The paper (Bailey, Watt & O'Brien 2016) reports no numbers but its settings; every
measure here is ours. Distances are on the character's surface
(:func:`rigmap.latent.control_scaling.surface`: mesh vertices of the face, joints of a
rig without a mesh) in the rig's unit (cm); controls in their own units.

- :func:`pca_dims` and :func:`scaled_against_unscaled` (§4.2): PCA sizes at 85 % and the
  held-out error of PCA alone, scaled against unscaled controls;
- :func:`latent_dim_sweep` (§6) and :func:`one_against_per_label` (§5.2, §7): held-out
  takes projected into a model (Eq 15) and mapped back (Eq 8);
- :func:`matching_rows` (§5.2): matching points per model pair, spread, distance;
- :func:`transition_smoothness` (§6 against Kovar et al. 2002): peak vertex acceleration
  and jerk around a switch over the training takes' 95th percentile, and the fraction of
  source frames a transition can start from;
- :func:`command_suites` (§5.3) and :func:`seed_spread` (repeats of one script).
"""

from __future__ import annotations

import itertools
import time

import numpy as np

from rigmap.latent.control_scaling import fit_control_scaling, surface
from rigmap.latent.gplvm import GPLVMSettings
from rigmap.latent.library import LabelledSet, fit_set
from rigmap.latent.model import LatentModel
from rigmap.latent.motion_graph import (
    WINDOW,
    blend_transition,
    find_transitions,
    surface_features,
)
from rigmap.latent.pca import fit_pca
from rigmap.latent.synthesis import Controller, Idle, Move, Play, Transition

GRAPH_THRESHOLD_CM = 0.2  # ours: per-frame RMS vertex distance over a motion-graph window


def surface_rms_cm(rig, P_true, P_hat) -> float:
    """RMS over frames and surface points of the distance between two poses' points."""
    a = surface(rig, rig.expand_used(np.asarray(P_true, dtype=np.float64)))
    b = surface(rig, rig.expand_used(np.asarray(P_hat, dtype=np.float64)))
    return float(np.sqrt(((a - b) ** 2).sum(-1).mean()))


def controls_rms(P_true, P_hat) -> float:
    return float(np.sqrt(((np.asarray(P_hat) - np.asarray(P_true)) ** 2).mean()))


def pca_dims(rig, P, variance: float) -> dict:
    """PCA components at ``variance`` of scaled (§4.1) and unscaled controls."""
    scaling = fit_control_scaling(rig, P)
    return {
        "scaled": int(fit_pca(scaling.scale(P), variance=variance).n_components_),
        "unscaled": int(fit_pca(P, variance=variance).n_components_),
    }


def scaled_against_unscaled(rig, P, P_test, sizes) -> list[dict]:
    """Held-out error of PCA alone at each size, scaled and unscaled (§4.2: scaled is
    worse in control space and better on the mesh)."""
    scaling = fit_control_scaling(rig, P)
    rows = []
    for k in sizes:
        k = min(int(k), P.shape[1], len(P))
        row: dict = {"pca_dims": k}
        for name, forward, back in (
            ("scaled", scaling.scale, scaling.unscale),
            ("unscaled", lambda Z: Z, lambda Z: np.clip(Z, scaling.lower, scaling.upper)),
        ):
            pca = fit_pca(forward(P), n_components=k)
            P_hat = back(pca.inverse_transform(pca.transform(forward(P_test))))
            row[f"{name}_controls_rms"] = controls_rms(P_test, P_hat)
            row[f"{name}_surface_rms_cm"] = surface_rms_cm(rig, P_test, P_hat)
        rows.append(row)
    return rows


def heldout_error(rig, model: LatentModel, P_test, *, max_iter: int = 100) -> dict:
    """Held-out poses projected into ``model`` (Eq 15) and mapped back (Eq 8)."""
    P_hat = model.to_controls(model.project(P_test, max_iter=max_iter))
    return {
        "controls_rms": controls_rms(P_test, P_hat),
        "surface_rms_cm": surface_rms_cm(rig, P_test, P_hat),
    }


def _fit(rig, entry: LabelledSet, settings: GPLVMSettings, fps: float, variance):
    """``variance``: a PCA variance fraction, or ``(fraction, n_components or None)``."""
    fraction, n_pca = variance if isinstance(variance, tuple) else (variance, None)
    start = time.perf_counter()
    model = fit_set(rig, entry, fps=fps, variance=fraction, n_pca=n_pca, settings=settings)
    return model, time.perf_counter() - start


def latent_dim_sweep(
    rig, sets, heldout, labels, dims, *, settings, fps, variance, fitted=None
) -> list[dict]:
    """Per label and latent dimension ``q``: held-out reconstruction error and fit time.
    ``fitted`` (a :class:`~rigmap.latent.library.FittedModels` made with ``settings``)
    stands in for the fit at ``settings.latent_dim``."""
    rows = []
    for label in labels:
        for q in dims:
            s = GPLVMSettings(**{**settings.__dict__, "latent_dim": int(q)})
            if fitted is not None and s == settings and label in fitted.models:
                model, seconds = fitted.models[label], fitted.fit_seconds[label]
            else:
                model, seconds = _fit(rig, sets[label], s, fps, variance)
            rows.append(
                {
                    "label": label,
                    "latent_dim": int(q),
                    "frames": sets[label].n_frames,
                    "pca_dims": int(model.pca.n_components_),
                    "fit_s": seconds,
                    **heldout_error(rig, model, heldout[label].values),
                }
            )
    return rows


KNEE_DROP = 0.90  # ours: a knee has made this fraction of the drop from the first to the last


def knee_dimension(errors: dict[int, float], drop: float = KNEE_DROP) -> int:
    """The smallest latent dimension that has made ``drop`` of the error's fall from the
    smallest dimension swept to the largest (ours; scale-free, so a label whose errors
    fall to near zero is judged by its shape, not by the fit's noise at the bottom)."""
    first, last = errors[min(errors)], errors[max(errors)]
    return min(q for q, e in errors.items() if e <= last + (1.0 - drop) * (first - last))


def merged_set(sets, labels) -> LabelledSet:
    """One labelled set of every take of ``labels`` (each take its own segment)."""
    names, takes = [], []
    for label in labels:
        names += sets[label].names
        takes += sets[label].takes
    return LabelledSet("+".join(labels), names, takes)


def one_against_per_label(rig, sets, heldout, labels, dims, *, settings, fps, variance):
    """One model of all ``labels`` against one model per label, at each latent dimension:
    held-out error over all labels' held-out takes (frame-weighted) and fit seconds."""
    rows = []
    test = np.vstack([heldout[label].values for label in labels])
    for q in dims:
        s = GPLVMSettings(**{**settings.__dict__, "latent_dim": int(q)})
        one, one_s = _fit(rig, merged_set(sets, labels), s, fps, variance)
        rows.append(
            {
                "models": "one for all",
                "latent_dim": int(q),
                "fit_s": one_s,
                **heldout_error(rig, one, test),
            }
        )
        P_hat, seconds = [], 0.0
        for label in labels:
            model, fit_s = _fit(rig, sets[label], s, fps, variance)
            seconds += fit_s
            P_hat.append(model.to_controls(model.project(heldout[label].values)))
        P_hat = np.vstack(P_hat)
        rows.append(
            {
                "models": "one per label",
                "latent_dim": int(q),
                "fit_s": seconds,
                "controls_rms": controls_rms(test, P_hat),
                "surface_rms_cm": surface_rms_cm(rig, test, P_hat),
            }
        )
    return rows


def matching_rows(table, labels) -> list[dict]:
    """Per unordered model pair: matching points, their spread and distance (cm)."""
    rows = []
    for a, b in itertools.combinations(labels, 2):
        m = table.pair(a, b)
        found = len(m) > 0
        rows.append(
            {
                "pair": f"{a}-{b}",
                "points": len(m),
                "candidates": m.candidates,
                "spread_latent": m.spread(),
                "distance_cm_median": float(np.median(m.distance_cm)) if found else None,
                "distance_cm_max": float(m.distance_cm.max()) if found else None,
            }
        )
    return rows


def per_frame_peaks(rig, P, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Per frame, the largest surface-point acceleration (cm/s²) and jerk (cm/s³)."""
    V = surface(rig, rig.expand_used(np.asarray(P, dtype=np.float64)))
    acc = np.linalg.norm(np.diff(V, 2, axis=0), axis=-1).max(-1) * fps**2
    jerk = np.linalg.norm(np.diff(V, 3, axis=0), axis=-1).max(-1) * fps**3
    return acc, jerk


def _window_peaks(rig, P, start: int, blend: int, fps: float) -> tuple[float, float]:
    lo, hi = max(0, start - blend), min(len(P), start + 2 * blend + 3)
    acc, jerk = per_frame_peaks(rig, P[lo:hi], fps)
    return float(acc.max()), float(jerk.max())


def ordered_pairs(labels, limit: int) -> list[tuple[str, str]]:
    """Ordered model pairs; ``limit`` > 0 keeps every k-th so the first ``limit`` spread out."""
    pairs = list(itertools.permutations(labels, 2))
    if limit and limit < len(pairs):
        pairs = [pairs[int(k)] for k in np.linspace(0, len(pairs) - 1, limit).round()]
    return pairs


def _our_transitions(rig, fitted, table, a, b, starts, seed, fps):
    """TRANSITION from seeded training frames of ``a``: peaks per switch and successes."""
    sets = fitted.sets
    peaks, successes = [], 0
    for s in range(starts):
        r = np.random.default_rng([seed, s, *(ord(c) for c in a + b)])
        take = sets[a].names[int(r.integers(len(sets[a].names)))]
        frame = int(r.integers(len(sets[a].take(take))))
        c = Controller(
            fitted.models,
            start=a,
            takes=sets,
            transitions=table,
            seed=seed + s,
            start_point=fitted.models[a].latent[sets[a].rows(take)[frame]],
        )
        P = c.run([Transition(b, idle_frames=2 * WINDOW)])
        entry = c.log[-1]
        successes += int(entry.success)
        peaks += [_window_peaks(rig, P, k, c.settings.blend_frames, fps) for k in entry.switches]
    return peaks, successes


def transition_smoothness(rig, fitted, table, pairs, *, starts: int, seed: int, fps: float):
    """Ours (TRANSITION, 12-frame blend) against the motion graph's lowest-distance
    transition between the same sets' takes, per ordered pair: peak acceleration and jerk
    around the switch over the training takes' 95th percentile, and the fraction of
    source frames a transition can start from (ours: TRANSITION's success rate from
    seeded frames; the graph's: frames with a transition under
    :data:`GRAPH_THRESHOLD_CM` RMS)."""
    sets = fitted.sets
    peaks = {label: [per_frame_peaks(rig, t, fps) for t in s.takes] for label, s in sets.items()}
    n_points = surface(rig, rig.expand_used(sets[pairs[0][0]].takes[0][:1])).shape[1]
    rows = []
    for a, b in pairs:
        p95_acc = float(
            np.percentile(np.concatenate([x for lab in (a, b) for x, _ in peaks[lab]]), 95)
        )
        p95_jerk = float(
            np.percentile(np.concatenate([j for lab in (a, b) for _, j in peaks[lab]]), 95)
        )
        ours, successes = _our_transitions(rig, fitted, table, a, b, starts, seed, fps)
        row = {
            "pair": f"{a}->{b}",
            "ours_peak_acc_rel_p95": max((x for x, _ in ours), default=np.nan) / p95_acc,
            "ours_peak_jerk_rel_p95": max((j for _, j in ours), default=np.nan) / p95_jerk,
            "ours_start_fraction": successes / starts,
        }
        features = [
            {n: surface_features(rig, v) for n, v in zip(sets[x].names, sets[x].takes, strict=True)}
            for x in (a, b)
        ]
        found = find_transitions(features[0], features[1], threshold=np.inf)
        limit = WINDOW * n_points * GRAPH_THRESHOLD_CM**2
        start_frames = {(t.source, t.i) for t in found if t.distance <= limit}
        row["graph_start_fraction"] = len(start_frames) / sets[a].n_frames
        row["graph_peak_acc_rel_p95"] = row["graph_peak_jerk_rel_p95"] = None
        if found:
            best = found[0]
            P, at = blend_transition(
                sets[a].take(best.source), sets[b].take(best.target), best.i, best.j
            )
            acc, jerk = _window_peaks(rig, P, at, WINDOW, fps)
            row["graph_peak_acc_rel_p95"], row["graph_peak_jerk_rel_p95"] = (
                acc / p95_acc,
                jerk / p95_jerk,
            )
        rows.append(row)
    return rows


def suite_commands(fitted, kind: str, n: int, seed: int, start: str):
    """``n`` seeded commands of one kind, valid in the model each runs in."""
    rng = np.random.default_rng([seed, len(kind)])
    labels = list(fitted.models)
    model, commands = start, []
    for k in range(n):
        names = fitted.sets[model].names
        take = names[int(rng.integers(len(names)))]
        if kind == "move":
            frame = int(rng.integers(len(fitted.sets[model].take(take))))
            commands.append(Move(take=take, frame=frame, path="graph" if k % 2 else "line"))
        elif kind == "idle":
            commands.append(Idle(int(rng.integers(12, 48))))
        elif kind == "transition":
            model = labels[
                (labels.index(model) + 1 + int(rng.integers(len(labels) - 1))) % len(labels)
            ]
            commands.append(Transition(model))
        else:
            commands.append(Play(take))
    return commands


def command_suites(fitted, table, *, n: int, seed: int) -> list[dict]:
    """Per command kind, a scripted suite of ``n`` commands: success rate and frames."""
    start = next(iter(fitted.models))
    rows = []
    for kind in ("move", "idle", "transition", "play"):
        c = Controller(fitted.models, start=start, takes=fitted.sets, transitions=table, seed=seed)
        c.run(suite_commands(fitted, kind, n, seed, start))
        entries = [e for e in c.log if type(e.command).__name__.lower() == kind]
        frames = [e.frames for e in entries]
        rows.append(
            {
                "command": kind.upper(),
                "count": len(entries),
                "success_rate": float(np.mean([e.success for e in entries])),
                "frames_median": float(np.median(frames)),
                "frames_max": int(max(frames)),
            }
        )
    return rows


def seed_spread(rig, runs: list[np.ndarray]) -> dict:
    """Repeats of one script with different seeds: the mean surface distance (cm) of each
    pair of runs over their common frames (> 0: the random force differs; small: the
    commands still decide the motion)."""
    distances = []
    for A, B in itertools.combinations(runs, 2):
        n = min(len(A), len(B))
        distances.append(surface_rms_cm(rig, A[:n], B[:n]))
    return {
        "runs": len(runs),
        "frames": [len(r) for r in runs],
        "pairwise_rms_cm_min": float(min(distances)) if distances else None,
        "pairwise_rms_cm_max": float(max(distances)) if distances else None,
    }
