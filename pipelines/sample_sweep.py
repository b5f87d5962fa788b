"""DVC stage ``sample_sweep``: the network's joint error against the number of supersamples.

Table 2 compares samplers at one sample count; this stage asks how many samples a sampler
needs. For every fraction ``f`` of ``sweep.fractions`` the network is fitted on the train
corpus plus the first ``n = round(f x budget.samples)`` samples of
``<paths.data>/<rig>/samples/<sampler>.npz`` — independent draws, so the first ``n`` are a
draw of ``n`` — and scored on the rig's test clips. Writes
``<paths.metrics>/<rig>/sample_sweep/nn-<sampler>-<n>.json``, which the report draws
(``joint_error_vs_supersamples.png``). Nothing is logged to MLflow: these are points of a
curve, not methods.

    python pipelines/sample_sweep.py rig=quadruped sampler=pca_gaussian
    python pipelines/sample_sweep.py rig=biped '+sweep.fractions=[0.25,1.0]'
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from animate import rig_from_config
from rigmap.evaluation.methods import TestSet, run_method
from rigmap.regression.fitting import fit_regressor, load_training_data, placement_of
from rigmap.stage import run_stage

DEFAULT_FRACTIONS = (0.0625, 0.125, 0.25, 0.5, 1.0)
SWEEP_FOLDER = "sample_sweep"


def sample_counts(fractions, total: int, available: int) -> list[int]:
    """``round(f x total)`` per fraction: distinct, positive, at most ``available``."""
    counts = []
    for fraction in fractions:
        if not 0 < float(fraction) <= 1:
            raise ValueError(f"sweep.fractions: expected numbers in (0, 1], got {fraction!r}")
        counts.append(max(1, round(float(fraction) * total)))
    too_many = [n for n in counts if n > available]
    if too_many:
        raise ValueError(
            f"sweep: {too_many} samples asked for, but the samples file holds {available} "
            f"(budget.samples = {total}); re-run the supersample stage"
        )
    return sorted(set(counts))


def run(cfg: DictConfig) -> list[Path]:
    regressor = getattr(hydra.utils.instantiate(cfg.regressor, _convert_="all"), "name", None)
    if regressor != "nn":
        raise ValueError(f"sample_sweep fits the network: expected regressor=nn, got {regressor!r}")
    sampler = str(cfg.sampler.name)
    if sampler == "none":
        raise ValueError("sample_sweep needs a sampler that draws samples, got sampler=none")
    fractions = OmegaConf.select(cfg, "sweep.fractions", default=list(DEFAULT_FRACTIONS))
    written = []
    with rig_from_config(cfg.rig) as rig:
        data = load_training_data(rig, cfg.paths.data, sampler)
        counts = sample_counts(fractions, int(cfg.budget.samples), data.sample_rows)
        base_rows = data.rows - data.sample_rows  # the corpus (and the rest pose, if added)
        placement = placement_of(rig, data)
        test_set = TestSet.load(rig, Path(cfg.paths.data) / rig.name)
        folder = Path(cfg.paths.metrics) / rig.name / SWEEP_FOLDER
        folder.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{SWEEP_FOLDER}.", dir=folder.parent))
        try:
            for n in counts:
                rows = slice(0, base_rows + n)
                subset = replace(
                    data, features=data.features[rows], controls=data.controls[rows], sample_rows=n
                )
                model = hydra.utils.instantiate(cfg.regressor, _convert_="all")
                mapping = fit_regressor(model, rig, subset, placement)
                evaluation = run_method(
                    rig, "nn", test_set, regressor=mapping, sampler=sampler,
                    extra={"samples": n, "training_rows": subset.rows},
                )  # fmt: skip
                path = evaluation.result.write_json(staging / f"nn-{sampler}-{n}.json")
                average = evaluation.result.average()
                print(
                    f"{rig.name} nn + {n} {sampler} samples: joint error "
                    f"{average['joint_error']:.4g} {evaluation.result.length_unit}², ground truth "
                    f"{average['ground_truth_error']:.4g}",
                    flush=True,
                )
                written.append(folder / path.name)
            if folder.exists():
                shutil.rmtree(folder)
            staging.rename(folder)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    return written


if __name__ == "__main__":
    run_stage(run)
