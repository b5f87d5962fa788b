"""Scoring one propagated edit on a study's held-out clips: the issue's "must show" numbers.

- the edit's scores (:mod:`rigmap.edits.scoring`) pooled over the held-out clips;
- the ablation (§1, §4: "both predictors beat either alone"): the same GP predictions
  solved with other weights — kinematic only, acceleration only (anchored to the source
  by a tiny kinematic regulariser), both without regularisers, the full solve;
- context dependence (Fig 6): the fraction of the full-strength edit carried, per root
  speed band, predicted against the ground truth's, and its correlation per frame with
  the ground truth's and with the root speed; for the half-steps edit (Fig 7) the
  same fraction on moving frames (root speed at least the walking gate's lower speed) is
  the averaging ratio (0.4–0.6 expected); the same per-band fractions on the study's
  walk ↔ stand transition clips (``context_transitions``, rig mode:
  :mod:`rigmap.edits.transitions`), whose other frames would not fill the bands between
  standing and walking;
- out-of-distribution input (Fig 4): on clips unlike the examples, the distance of the
  result from the source and how well the kinematic variance separates their frames from
  the held-out ones (AUROC; 1 = perfectly);
- foot skate (§7.3: the paper cleans contacts up afterwards): on the frames where the
  source plants a foot (:func:`rigmap.map.contacts.detect_contacts`), the mean horizontal
  slide of that foot per frame in cm, in the source, the ground truth and the result.

Speed bands (cm/s) are ours.
"""

from __future__ import annotations

import itertools

import numpy as np
from sklearn.metrics import roc_auc_score

from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import EditModel
from rigmap.edits.representation import TargetTrack
from rigmap.edits.scoring import Tally, edit_fraction, score_clip
from rigmap.edits.study import StudyData, weights_from
from rigmap.map.contacts import detect_contacts, foot_skate

SPEED_BANDS_CM_S = (0.0, 10.0, 20.0, 40.0, 80.0, np.inf)  # ours


def evaluate_edit(
    data: StudyData, edit: Edit, model: EditModel, results: list[TargetTrack], ablation: dict
) -> dict:
    """Scores, ablation rows and context measures of one edit (see the module docstring)."""
    cm = data.subject.cm_per_unit
    truths = [edit.apply(source.track, cm, data.subject.skeleton) for source in data.heldout]
    total = Tally()
    clips = {}
    for source, truth, result in zip(data.heldout, truths, results, strict=True):
        tally = score_clip(source.track, truth, result, data.scale, data.subject.relative_cm)
        clips[source.track.source] = tally.summary()
        total.merge(tally)
    tallies = {name: Tally() for name in ablation}
    for source, truth in zip(data.heldout, truths, strict=True):
        predictions = model.predict(source)
        for name, weights in ablation.items():
            solved = model.apply(source, weights_from(weights), predictions=predictions)
            tallies[name].merge(score_clip(source.track, truth, solved, data.scale, None))
    rows = {name: tally.summary() for name, tally in tallies.items()}
    return {
        "edit": edit.name,
        "description": edit.description,
        "mode": edit.mode,
        "heldout": total.summary(),
        "clips": clips,
        "ablation": rows,
        "context": context_dependence(data, edit, truths, results),
        "context_transitions": _transitions_context(data, edit, model),
        "out_of_distribution": out_of_distribution(data, model),
        "foot_skate_cm": foot_skate_report(data, truths, results),
    }


def foot_skate_report(data: StudyData, truths, results) -> dict | None:
    """Slide of the source's planted feet (cm per frame), pooled frame-weighted over clips."""
    if not data.feet:
        return None
    names = data.subject.joint_names
    sums = {"source": 0.0, "truth": 0.0, "result": 0.0}
    frames = 0
    for source, truth, result in zip(data.heldout, truths, results, strict=True):
        world = data.subject.positions(source.track)
        contacts = detect_contacts(world, data.feet, names, source.track.fps)
        planted = int((contacts.planted[1:] & contacts.planted[:-1]).sum())
        if planted == 0:
            continue
        for key, track in (("source", source.track), ("truth", truth), ("result", result)):
            sums[key] += planted * foot_skate(data.subject.positions(track), contacts, names)
        frames += planted
    if frames == 0:
        return None
    return {**{k: v / frames for k, v in sums.items()}, "planted_frames": frames}


def _transitions_context(data: StudyData, edit: Edit, model: EditModel) -> dict | None:
    """:func:`context_dependence` on the study's walk ↔ stand transition clips (None
    without them)."""
    if not data.transitions:
        return None
    cm, skeleton = data.subject.cm_per_unit, data.subject.skeleton
    truths = [edit.apply(source.track, cm, skeleton) for source in data.transitions]
    results = [model.apply(source) for source in data.transitions]
    report = context_dependence(data, edit, truths, results, clips=data.transitions)
    return {**report, "clips": [s.track.source for s in data.transitions]}


def context_dependence(data: StudyData, edit: Edit, truths, results, clips=None) -> dict:
    """Mean fraction of the full edit carried per root-speed band, predicted and true, on
    ``clips`` (the held-out clips unless given)."""
    cm = data.subject.cm_per_unit
    full = edit.full()
    speeds, predicted, true = [], [], []
    clips = data.heldout if clips is None else clips
    for source, truth, result in zip(clips, truths, results, strict=True):
        strongest = full.apply(source.track, cm, data.subject.skeleton)
        speeds.append(edit.root_speed_cm_s(source.track, cm))
        predicted.append(edit_fraction(source.track, result, strongest, data.scale))
        true.append(edit_fraction(source.track, truth, strongest, data.scale))
    speed, p, t = (np.concatenate(a) for a in (speeds, predicted, true))
    speed = np.maximum(speed, 0.0)  # the 0.5 s smoothing leaves -1e-16 on some standing frames
    bands = []
    for low, high in itertools.pairwise(SPEED_BANDS_CM_S):
        inside = (speed >= low) & (speed < high) & np.isfinite(p)
        bands.append(
            {
                "speed_cm_s": [low, high],
                "frames": int(inside.sum()),
                "predicted_fraction": _mean(p[inside]),
                "true_fraction": _mean(t[inside]),
            }
        )
    moving = (speed >= edit.walking_speeds_cm_s[0]) & np.isfinite(p)
    finite = np.isfinite(p) & np.isfinite(t)
    return {
        "bands": bands,
        "moving_fraction": _mean(p[moving]),
        "correlation_with_truth": _correlation(p[finite], t[finite]),
        "correlation_with_speed": _correlation(p[finite], speed[finite]),
    }


def _correlation(a: np.ndarray, b: np.ndarray) -> float | None:
    """Pearson's r; None where either side is constant (an ungated edit's truth)."""
    if len(a) > 2 and a.std() > 0 and b.std() > 0:
        return float(np.corrcoef(a, b)[0, 1])
    return None


def out_of_distribution(data: StudyData, model: EditModel) -> dict | None:
    """Fig 4: on clips unlike the examples the result should stay near the source, and the
    kinematic GP's variance should tell their frames from the held-out ones (AUROC)."""
    if not data.unlike:
        return None
    distance, variance = {}, {}
    for group, clips in (("heldout", data.heldout), ("unlike", data.unlike)):
        moved, spread = [], []
        for source in clips:
            predictions = model.predict(source)
            result = model.apply(source, predictions=predictions)
            moved.append(data.scale.scaled(result) - data.scale.scaled(source.track))
            spread.append(predictions[0].variance)
        distance[group] = float(np.sqrt(np.mean(np.concatenate(moved) ** 2)))
        variance[group] = np.concatenate(spread)
    labels = np.r_[np.zeros(len(variance["heldout"])), np.ones(len(variance["unlike"]))]
    scores = np.r_[variance["heldout"], variance["unlike"]]
    return {
        "rms_distance_to_source_std": distance,
        "mean_kinematic_variance": {k: float(v.mean()) for k, v in variance.items()},
        "variance_auroc": float(roc_auc_score(labels, scores)),
        "clips": [s.track.source for s in data.unlike],
    }


def _mean(values: np.ndarray) -> float | None:
    return float(np.mean(values)) if len(values) else None
