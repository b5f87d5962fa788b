"""DVC stage ``sample_sweep``: the network's joint error against the number of supersamples.

For every fraction ``f`` of ``sweep.fractions`` the network is fitted on the train corpus
plus the first ``round(f x budget.samples)`` samples of
``<paths.data>/<rig>/samples/<sampler>.npz`` and scored on the rig's test clips. Writes
``<paths.metrics>/<rig>/sample_sweep/nn-<sampler>-<n>.json``, which the report draws
(``joint_error_vs_supersamples.png``); see :mod:`rigmap.evaluation.sample_sweep`.
With ``regressor=nn_joint_space sampler=none`` it sweeps the joint-space network's own
draws instead, into ``<paths.metrics>/<rig>/sample_sweep_joint_space/``.

    python pipelines/sample_sweep.py rig=quadruped sampler=pca_gaussian
    python pipelines/sample_sweep.py rig=biped '+sweep.fractions=[0.25,1.0]'
    python pipelines/sample_sweep.py rig=quadruped regressor=nn_joint_space sampler=none
"""

from __future__ import annotations

from pathlib import Path

import hydra
from omegaconf import DictConfig, OmegaConf

from rigmap.app.inputs import layout_of, rig_from_config
from rigmap.app.objects import sampler_name
from rigmap.app.stage import run_stage
from rigmap.evaluation.sample_sweep import (
    DEFAULT_FRACTIONS,
    joint_space_sweep,
    sample_counts,
    sample_sweep,
)

__all__ = ["run", "sample_counts"]


def run(cfg: DictConfig) -> list[Path]:
    with rig_from_config(
        cfg.rig, cfg.get("executor")
    ) as rig:  # a DCC rig's worker processes end with the sweep
        fractions = OmegaConf.select(cfg, "sweep.fractions", default=list(DEFAULT_FRACTIONS))
        make = lambda: hydra.utils.instantiate(cfg.regressor, _convert_="all")  # noqa: E731
        if OmegaConf.select(cfg, "regressor._target_", default="").endswith(
            "JointSpaceNetworkRegressor"
        ):
            return joint_space_sweep(rig, layout_of(cfg), make, fractions=fractions)
        return sample_sweep(
            rig,
            layout_of(cfg),
            make,
            sampler=sampler_name(cfg.sampler),
            total_samples=int(cfg.budget.samples),
            fractions=fractions,
        )


if __name__ == "__main__":
    run_stage(run)
