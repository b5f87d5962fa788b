"""DVC stage ``latent``: latent synthesis (Bailey, Watt & O'Brien 2016; seed 003), one rig a run.

One script for the four steps of :mod:`rigmap.latent.steps` (fit, match, synthesize,
evaluate): all four in order, or the one ``+latent_step`` names; settings in
``conf/latent/default.yaml`` (``latent.*``), and with ``latent.log_to_mlflow`` a parent
MLflow run per step in the rig's experiment:

    python pipelines/latent.py rig=face                       # the four steps
    python pipelines/latent.py rig=face +latent_step=fit latent.max_iter=100
    python pipelines/latent.py rig=face +latent_step=evaluate
"""

from __future__ import annotations

from omegaconf import DictConfig

from rigmap.app.latent import run_steps
from rigmap.app.stage import run_stage


def run(cfg: DictConfig):
    return run_steps(cfg)


if __name__ == "__main__":
    run_stage(run)
