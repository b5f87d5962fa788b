"""What the ``edits`` stage's steps do, from a plain config dict and a :class:`Layout`.

Each runs over the subjects ``edits.run`` names, in one process (each stage's start-up,
torch and the rigs, costs more than the edits of a subject); the stage runs the three.

- :func:`run_fit`: every edit's model on the subject's examples →
  ``models/<subject>/edits/<edit>.npz`` and ``fit.json`` (hyper-parameters, iterations, s);
- :func:`run_apply`: each model on the held-out clips → ``data/<subject>/edits/<edit>.npz``
  (the propagated tracks' values, one array per clip);
- :func:`run_evaluate`: the scores → ``metrics/<subject>/edits/detail/<edit>.json`` (per
  clip, too), ``summary.json`` and the tables ``edits.csv``, ``ablation.csv``, ``context.csv``;
- :func:`run_add` (``rigmap edits add``; not a stage): incremental refinement (§3) played
  with each edit's ground truth on the held-out clips, suggested (highest-variance) against
  random fixes over several seeds → ``metrics/<subject>/edits/refinement/<edit>.json``,
  ``.csv`` (every run's rounds) and ``<edit>_summary.csv`` (per round: the suggestion beside
  random's mean, std, min and max).
"""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

import numpy as np

from rigmap.edits.evaluation import evaluate_edit
from rigmap.edits.incremental import compare_choices
from rigmap.edits.mirror import subject_mirror
from rigmap.edits.propagation import load_model, save_model
from rigmap.edits.representation import TargetError
from rigmap.edits.study import (
    apply_edit,
    edits_for,
    fit_edit,
    load_study,
    model_from,
    weights_from,
)
from rigmap.store import Layout, atomic_file, json_ready, write_json_atomic, write_text_atomic
from rigmap.store.layout import EDITS

TABLE_COLUMNS = (
    "edit_error_std",
    "source_error_std",
    "joint_rmse_cm",
    "source_joint_rmse_cm",
    "transfer",
    "leak_std",
    "leak_cm",
    "jerk_ratio",
    "drift_std",
    "root_drift_cm",
)
#: per edit and held-out take (``takes.csv``): the issue's generalisation-across-takes numbers
TAKE_COLUMNS = (
    "edit_error_std",
    "source_error_std",
    "transfer",
    "leak_std",
    "leak_cm",
    "joint_rmse_cm",
    "source_joint_rmse_cm",
)
#: per edit on the held-out clips (``edits.csv``): Fig 6's context dependence, per frame the
#: carried fraction's correlation with the ground truth's and with the root speed
CONTEXT_COLUMNS = ("correlation_with_truth", "correlation_with_speed")
ABLATION_COLUMNS = ("edit_error_std", "transfer", "jerk_ratio", "drift_std", "leak_std")


def _subjects(config: dict) -> list[str]:
    """The subjects a run covers (``edits.run``), checked before any work with the other
    settings every stage reads (``edits.names``, ``edits.weights``, ``edits.ablation``)."""
    names = _name_list(config, "run")
    _name_list(config, "names")
    weights_from(config.get("weights") or {}, "edits.weights")
    for solve, weights in dict(config.get("ablation") or {}).items():
        weights_from(weights, f"edits.ablation.{solve}")
    unknown = [name for name in names if name not in config["subjects"]]
    if unknown or not names:
        raise TargetError(
            f"edits.run {names} must name subjects among {sorted(config['subjects'])}"
        )
    return names


def _name_list(config: dict, key: str) -> list[str]:
    """``edits.<key>``: a list of names (a bare string would be read letter by letter)."""
    value = config.get(key)
    if not isinstance(value, list | tuple) or not all(isinstance(v, str) for v in value):
        raise TargetError(
            f"edits.{key}={value!r}: expected a list of names, e.g. "
            f"'edits.{key}=[{value if isinstance(value, str) else '...'}]'"
        )
    return list(value)


def _setup(config: dict, subject: str):
    spec = config["subjects"][subject]
    data = load_study(subject, spec)
    edits = edits_for(config["catalogue"], list(config["names"]), data.subject.mode, spec, subject)
    for edit in edits.values():
        edit.check(data.train[0].track)
    return subject, data, edits


def run_fit(config: dict, layout: Layout) -> list[Path]:
    return [_fit(config, subject, layout) for subject in _subjects(config)]


def run_apply(config: dict, layout: Layout) -> list[Path]:
    return [_apply(config, subject, layout) for subject in _subjects(config)]


def run_evaluate(config: dict, layout: Layout) -> list[Path]:
    return [_evaluate(config, subject, layout) for subject in _subjects(config)]


def run_add(config: dict, layout: Layout) -> list[Path]:
    settings = refine_settings(config)
    return [_add(config, subject, layout, settings) for subject in _subjects(config)]


# ours: 5 rounds of 2 segments of 12 frames (0.5 s at 24 fps), random fixes over 5 seeds
# (seed, seed + 1, ...), the plain highest-variance suggestion beside them ("choices" may
# add "variance_clips", rigmap.edits.incremental)
REFINE_DEFAULTS = {
    "rounds": 5,
    "per_round": 2,
    "segment": 12,
    "seed": 0,
    "random_seeds": 5,
    "choices": ["variance"],
}
#: the smallest value of each count (ours: one round, segment, seed at least)
REFINE_MINIMA = {"rounds": 1, "per_round": 1, "segment": 1, "seed": 0, "random_seeds": 1}


def refine_settings(config: dict) -> dict:
    """``edits.refine`` over :data:`REFINE_DEFAULTS`, checked before any work: an unknown
    key or a count that is not an integer is an error naming it."""
    given = dict(config.get("refine") or {})
    unknown = sorted(set(given) - set(REFINE_DEFAULTS))
    if unknown:
        raise TargetError(
            f"edits.refine: unknown setting(s) {unknown}; the settings are "
            f"{sorted(REFINE_DEFAULTS)}"
        )
    settings = {**REFINE_DEFAULTS, **given}
    for key, value in settings.items():
        if key != "choices" and (
            isinstance(value, bool) or not isinstance(value, int) or value < REFINE_MINIMA[key]
        ):
            raise TargetError(
                f"edits.refine.{key} must be an integer >= {REFINE_MINIMA[key]}, got {value!r}"
            )
    if isinstance(settings["choices"], str):
        raise TargetError(
            f"edits.refine.choices must be a list, e.g. [variance,variance_clips]; "
            f"got {settings['choices']!r}"
        )
    settings["choices"] = [str(c) for c in settings["choices"]]
    return settings


def _add(config: dict, subject: str, layout: Layout, settings: dict) -> Path:
    subject, data, edits = _setup(config, subject)
    folder = layout.edits_refinement(subject)
    mirror = subject_mirror(data.subject) if config.get("mirror", False) else None
    cm = data.subject.cm_per_unit

    for name, edit in edits.items():
        skeleton = data.subject.skeleton
        examples = [(source, edit.apply(source.track, cm, skeleton)) for source in data.train]
        truths = [edit.apply(source.track, cm, skeleton) for source in data.heldout]
        report = compare_choices(
            lambda: model_from(data, config),
            data.scale,
            examples,
            data.heldout,
            truths,
            choices=settings["choices"],
            random_seeds=int(settings["random_seeds"]),
            seed=int(settings["seed"]),
            rounds=int(settings["rounds"]),
            per_round=int(settings["per_round"]),
            segment=int(settings["segment"]),
            mirror=mirror,
            relative_cm=data.subject.relative_cm,
        )
        rows = [{"choice": c, "seed": "", **row} for c in settings["choices"] for row in report[c]]
        rows += [
            {"choice": "random", "seed": seed, **row}
            for seed, table in report["random"].items()
            for row in table
        ]
        write_text_atomic(folder / f"{name}.csv", _csv(rows))
        write_text_atomic(folder / f"{name}_summary.csv", _csv(report["summary"]))
        write_json_atomic(folder / f"{name}.json", json_ready({**report, "settings": settings}))
    return folder


def _fit(config: dict, subject: str, layout: Layout) -> Path:
    subject, data, edits = _setup(config, subject)
    folder = layout.app_models(subject, EDITS)
    infos = {}
    for name, edit in edits.items():
        model, infos[name] = fit_edit(data, edit, config)
        save_model(model, folder / f"{name}.npz")
    return write_json_atomic(folder / "fit.json", json_ready(infos))


def _apply(config: dict, subject: str, layout: Layout) -> Path:
    subject, data, edits = _setup(config, subject)
    models = layout.app_models(subject, EDITS)
    out = layout.app_data(subject, EDITS)
    for name in edits:
        model = load_model(models / f"{name}.npz")
        start = time.perf_counter()
        results = apply_edit(data, model)
        seconds = time.perf_counter() - start
        arrays = {f"clip_{k}": r.values for k, r in enumerate(results)}
        arrays["sources"] = np.array([s.track.source for s in data.heldout])
        arrays["apply_s"] = np.array(seconds)
        with atomic_file(out / f"{name}.npz", suffix=".npz") as temporary:
            np.savez(temporary, **arrays)
    return out


def _evaluate(config: dict, subject: str, layout: Layout) -> Path:
    subject, data, edits = _setup(config, subject)
    models = layout.app_models(subject, EDITS)
    applied = layout.app_data(subject, EDITS)
    folder = layout.app_metrics(subject, EDITS)
    summary, takes = {}, {}
    for name, edit in edits.items():
        model = load_model(models / f"{name}.npz")
        with np.load(applied / f"{name}.npz", allow_pickle=False) as stored:
            results = [
                s.track.with_values(stored[f"clip_{k}"], source=f"{s.track.source} (propagated)")
                for k, s in enumerate(data.heldout)
            ]
            apply_s = float(stored["apply_s"])
        report = evaluate_edit(data, edit, model, results, dict(config["ablation"]))
        frames = sum(s.track.n_frames for s in data.heldout)
        report["apply_frames_per_s"] = frames / apply_s if apply_s > 0 else None
        write_json_atomic(folder / "detail" / f"{name}.json", json_ready(report))
        summary[name] = {
            **report["heldout"],
            "moving_fraction": report["context"]["moving_fraction"],
            "apply_frames_per_s": report["apply_frames_per_s"],
        }
        summary[name]["ablation"] = report["ablation"]
        summary[name]["context"] = report["context"]
        if report["context_transitions"] is not None:
            summary[name]["context_transitions"] = report["context_transitions"]
        summary[name]["out_of_distribution"] = report["out_of_distribution"]
        takes[name] = report["clips"]
    _write_tables(folder, summary, takes)
    if data.notes:  # a T-pose cut, capture glitches repaired: said where the numbers are
        summary["clips_read"] = {"notes": list(data.notes)}
    return write_json_atomic(folder / "summary.json", json_ready(summary))


def _write_tables(folder: Path, summary: dict, takes: dict) -> None:
    rows = [
        {"edit": n, **{c: s[c] for c in TABLE_COLUMNS}}
        | {f"context_{c}": s["context"][c] for c in CONTEXT_COLUMNS}
        for n, s in summary.items()
    ]
    write_text_atomic(folder / "edits.csv", _csv(rows))
    rows = [
        {"edit": n, "take": Path(source).stem, "frames": int(scores["frames"])}
        | {c: scores[c] for c in TAKE_COLUMNS}
        for n, clips in takes.items()
        for source, scores in clips.items()
    ]
    write_text_atomic(folder / "takes.csv", _csv(rows))
    rows = [
        {"edit": n, "solve": solve, **{c: r[c] for c in ABLATION_COLUMNS}}
        for n, s in summary.items()
        for solve, r in s["ablation"].items()
    ]
    write_text_atomic(folder / "ablation.csv", _csv(rows))
    rows = [
        {
            "edit": n,
            "clips": clips,
            "speed_low_cm_s": b["speed_cm_s"][0],
            "speed_high_cm_s": b["speed_cm_s"][1],
            "frames": b["frames"],
            "predicted_fraction": b["predicted_fraction"],
            "true_fraction": b["true_fraction"],
        }
        for n, s in summary.items()
        for clips, key in (("heldout", "context"), ("transitions", "context_transitions"))
        if key in s
        for b in s[key]["bands"]
    ]
    write_text_atomic(folder / "context.csv", _csv(rows))


def _csv(rows: list[dict]) -> str:
    stream = io.StringIO()
    writer = csv.DictWriter(stream, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    return stream.getvalue()
