"""DVC stage ``sample_sweep``: the network's joint error against the number of supersamples.

For every fraction ``f`` of ``sweep.fractions`` the network is fitted on the train corpus
plus the first ``round(f x budget.samples)`` samples of
``<paths.data>/<rig>/samples/<sampler>.npz`` and scored on the rig's test clips. Writes
``<paths.metrics>/<rig>/sample_sweep/nn-<sampler>-<n>.json``, which the report draws
(``joint_error_vs_supersamples.png``); see :mod:`rigmap.evaluation.sample_sweep`.
With ``regressor=nn_joint_space sampler=none`` it sweeps the joint-space network's own
draws instead, into ``<paths.metrics>/<rig>/sample_sweep_joint_space/``, at
``sweep.joint_space_fractions`` when the experiment sets it (quick: 3 points) and
``sweep.fractions`` is not given.

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

__all__ = ["run", "sample_counts", "sweep_fractions"]


def is_joint_space(cfg: DictConfig) -> bool:
    target = OmegaConf.select(cfg, "regressor._target_", default="")
    return str(target).endswith("JointSpaceNetworkRegressor")


def sweep_fractions(cfg: DictConfig, *, joint_space: bool) -> list:
    """``sweep.fractions`` if given; else, for the joint-space sweep, the experiment's own
    ``sweep.joint_space_fractions`` (quick: 3 points, each a fresh fit); else all five."""
    given = OmegaConf.select(cfg, "sweep.fractions", default=None)
    own = OmegaConf.select(cfg, "sweep.joint_space_fractions", default=None)
    if given is None and joint_space and own is not None:
        return list(own)  # checked where they are used, like sweep.fractions
    return list(given if given is not None else DEFAULT_FRACTIONS)


def run(cfg: DictConfig) -> list[Path]:
    with rig_from_config(
        cfg.rig, cfg.get("executor")
    ) as rig:  # a DCC rig's worker processes end with the sweep
        make = lambda: hydra.utils.instantiate(cfg.regressor, _convert_="all")  # noqa: E731
        if is_joint_space(cfg):
            fractions = sweep_fractions(cfg, joint_space=True)
            return joint_space_sweep(rig, layout_of(cfg), make, fractions=fractions)
        fractions = sweep_fractions(cfg, joint_space=False)
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
