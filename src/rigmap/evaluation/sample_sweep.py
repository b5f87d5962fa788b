"""The network's joint error against the number of supersamples it is trained with.

Table 2 compares samplers at one sample count; the sweep asks how many samples a sampler
needs. For every fraction ``f`` the network is fitted on the train corpus plus the first
``n = round(f x total)`` samples of the sampler's file — independent draws, so the first
``n`` are a draw of ``n`` — and scored on the rig's test clips. The results are written
together as one folder, ``metrics/<rig>/sample_sweep/nn-<sampler>-<n>.json``. Nothing is
logged to MLflow: these are points of a curve, not methods.

:func:`joint_space_sweep` asks the same of the joint-space network (issue #15, item 3),
whose samples are its own draws (PCA-Gaussian around the corpus, per-control around it and
uniform over the soft ranges, :mod:`rigmap.regression.joint_space_training`): for every
fraction every draw count is scaled, ``n_gaussian = round(f x G)``, ``n_local = round(f x L)``
and ``n_wide = round(f x W)``, a fresh network is
fitted and scored, into ``metrics/<rig>/sample_sweep_joint_space/nn_joint_space-draws-<n>.json``
(``n`` the draws in all). As in the network's sweep the epochs are fixed, so more samples
also mean more optimiser steps: the curve is what a user gets by asking for more samples.
The fraction 1 is the fit stage's own network: when ``models/<rig>/nn_joint_space-none-none``
holds a fit with the same parameters on the same training rows (``fit.json``'s digest), the
sweep scores that model instead of fitting it again (the same seeded fit, so the same
scores; it was about half the sweep's time).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError
from rigmap.store import Layout, ModelId, write_folder_atomic

DEFAULT_FRACTIONS = (0.0625, 0.125, 0.25, 0.5, 1.0)
SWEEP_FOLDER = "sample_sweep"
JOINT_SPACE_SWEEP_FOLDER = "sample_sweep_joint_space"
Log = Callable[[str], None]


def _print(line: str) -> None:
    print(line, flush=True)  # one line per fit, seen as it happens under DVC


class SweepInputError(RigmapError, ValueError):
    """A sweep that cannot run: wrong regressor or sampler, or fractions the file cannot give."""


def sample_counts(fractions: Sequence[float], total: int, available: int) -> list[int]:
    """``round(f x total)`` per fraction: distinct, positive, at most ``available``."""
    counts = []
    for fraction in fractions:
        if not 0 < float(fraction) <= 1:
            raise SweepInputError(f"sweep.fractions: expected numbers in (0, 1], got {fraction!r}")
        counts.append(max(1, round(float(fraction) * total)))
    too_many = [n for n in counts if n > available]
    if too_many:
        raise SweepInputError(
            f"sweep: {too_many} samples asked for, but the samples file holds {available} "
            f"(budget.samples = {total}); re-run the supersample stage"
        )
    return sorted(set(counts))


def sample_sweep(
    rig,
    layout: Layout,
    make_network: Callable[[], Any],
    *,
    sampler: str,
    total_samples: int,
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    log: Log = _print,
) -> list[Path]:
    """Fit a fresh ``make_network()`` per sample count, score it, write the sweep's folder."""
    from rigmap.evaluation.methods import TestSet, run_method
    from rigmap.regression.fitting import fit_regressor, load_training_data, placement_of

    regressor = getattr(make_network(), "name", None)
    if regressor != "nn":
        raise SweepInputError(
            f"sample_sweep fits the network: expected regressor=nn, got {regressor!r}"
        )
    if sampler == "none":
        raise SweepInputError("sample_sweep needs a sampler that draws samples, got sampler=none")
    data = load_training_data(rig, layout.data, sampler)
    counts = sample_counts(fractions, int(total_samples), data.sample_rows)
    base_rows = data.rows - data.sample_rows  # the corpus (and the rest pose, if added)
    placement = placement_of(rig, data)
    test_set = TestSet.load(rig, layout.rig_data(rig.name))
    folder = layout.metrics_folder(rig.name, SWEEP_FOLDER)
    names: list[str] = []

    def fill(staging: Path) -> None:
        for n in counts:
            rows = slice(0, base_rows + n)
            subset = replace(
                data, features=data.features[rows], controls=data.controls[rows], sample_rows=n
            )
            mapping = fit_regressor(make_network(), rig, subset, placement)
            evaluation = run_method(
                rig,
                "nn",
                test_set,
                regressor=mapping,
                sampler=sampler,
                extra={"samples": n, "training_rows": subset.rows},
            )
            names.append(evaluation.result.write_json(staging / f"nn-{sampler}-{n}.json").name)
            average = evaluation.result.average()
            log(
                f"{rig.name} nn + {n} {sampler} samples: joint error "
                f"{average['joint_error']:.4g} {evaluation.result.length_unit}², ground truth "
                f"{average['ground_truth_error']:.4g}"
            )

    write_folder_atomic(folder, fill)
    return [folder / name for name in names]


def joint_space_sweep(
    rig,
    layout: Layout,
    make_network: Callable[[], Any],
    *,
    fractions: Sequence[float] = DEFAULT_FRACTIONS,
    reuse_fit: bool = True,
    log: Log = _print,
) -> list[Path]:
    """Fit a fresh joint-space network per fraction of its draws, score it, write the folder.

    With ``reuse_fit`` a fraction whose network the fit stage already trained on these rows
    (:func:`fitted_model`) is scored from ``models/`` instead of being fitted again.
    """
    from rigmap.evaluation.methods import Method, RegressorGuess, TestSet, run_method
    from rigmap.regression.fitting import fit_regressor, load_training_data, placement_of

    template = make_network()
    counts, draws = _joint_space_draws(template, fractions)
    data = load_training_data(rig, layout.data, "none")
    placement = placement_of(rig, data)
    test_set = TestSet.load(rig, layout.rig_data(rig.name))
    method = Method("nn_joint_space", RegressorGuess("nn_joint_space", title="Joint-space NN"))
    fitted_folder = layout.model(rig.name, ModelId("nn_joint_space"))
    # the fit stage's network can only be the fraction with all the draws: read it once
    saved = fitted_model(fitted_folder, template, rig, data) if reuse_fit else None
    folder = layout.metrics_folder(rig.name, JOINT_SPACE_SWEEP_FOLDER)
    names: list[str] = []

    def fill(staging: Path) -> None:
        for draw in draws:
            n_gaussian, n_local, n_wide = draw
            network = make_network().set_params(
                n_gaussian=n_gaussian, n_local=n_local, n_wide=n_wide
            )
            mapping = saved if draw == counts else None
            if mapping is not None:
                log(
                    f"{rig.name} nn_joint_space + {sum(counts)} draws: scoring the fit stage's "
                    f"model {fitted_folder} (same parameters, same training rows)"
                )
            else:
                mapping = fit_regressor(network, rig, data, placement, log=lambda line: None)
            n = sum(draw)
            evaluation = run_method(
                rig,
                method,
                test_set,
                regressor=mapping,
                sampler="none",
                extra={
                    "samples": n,
                    "n_gaussian": n_gaussian,
                    "n_local": n_local,
                    "n_wide": n_wide,
                    "training_rows": data.rows + n,
                },
            )
            path = staging / f"nn_joint_space-draws-{n}.json"
            names.append(evaluation.result.write_json(path).name)
            average, unit = evaluation.result.average(), evaluation.result.length_unit
            log(
                f"{rig.name} nn_joint_space + {n} draws ({n_gaussian} around the corpus, "
                f"{n_local} per control, {n_wide} wide): joint error "
                f"{average['joint_error']:.4g} {unit}², "
                f"ground truth {average['ground_truth_error']:.4g}"
            )

    write_folder_atomic(folder, fill)
    return [folder / name for name in names]


def _joint_space_draws(
    template: Any, fractions: Sequence[float]
) -> tuple[tuple[int, int, int], list[tuple[int, int, int]]]:
    """The network's own draw counts (around the corpus, per control, wide) and each
    fraction's, smallest first; a clear error for another regressor or bad fractions."""
    if getattr(template, "name", None) != "nn_joint_space":
        raise SweepInputError(
            "joint_space_sweep fits the joint-space network: expected regressor=nn_joint_space, "
            f"got {getattr(template, 'name', None)!r}"
        )
    counts = (int(template.n_gaussian), int(template.n_local), int(template.n_wide))
    if sum(counts) < 1:
        raise SweepInputError(
            "joint_space_sweep: the network draws no poses (regressor.n_gaussian, "
            "regressor.n_local and regressor.n_wide are all 0), so there is nothing to sweep"
        )
    draws = []
    for fraction in fractions:
        if not 0 < float(fraction) <= 1:
            raise SweepInputError(f"sweep.fractions: expected numbers in (0, 1], got {fraction!r}")
        draws.append(tuple(round(float(fraction) * count) for count in counts))
    return counts, sorted(set(draws), key=sum)


#: parameters that change what a fit prints, not what it learns
_PRESENTATION_PARAMS = frozenset({"progress"})


def fitted_model(folder: Path, network, rig, data) -> Any | None:
    """The mapping saved in ``folder`` if it is ``network`` fitted on ``data``'s rows, else None.

    Both must hold: ``fit.json`` records the same training-row digest
    (:meth:`~rigmap.regression.fitting.TrainingData.digest`) and the saved regressor's
    parameters equal ``network``'s (all but :data:`_PRESENTATION_PARAMS`). A fit is seeded,
    so such a model is what fitting ``network`` again would give.
    """
    from rigmap.regression import load_regressor

    record_path = folder / "fit.json"
    if not record_path.is_file():
        return None
    try:
        record = json.loads(record_path.read_text())
    except json.JSONDecodeError as error:
        raise SweepInputError(
            f"{record_path}: not valid JSON ({error}); re-run the fit stage "
            f"(`dvc repro fit_nn_joint_space`) or delete {folder}"
        ) from None
    if record.get("rows", {}).get("sha256") != data.digest():
        return None
    mapping = load_regressor(folder, rig=rig)
    saved, wanted = mapping.regressor.get_params(), network.get_params()
    if {k: v for k, v in saved.items() if k not in _PRESENTATION_PARAMS} != {
        k: v for k, v in wanted.items() if k not in _PRESENTATION_PARAMS
    }:
        return None
    return mapping
