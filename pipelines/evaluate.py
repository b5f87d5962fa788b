"""DVC stages ``evaluate``, ``evaluate_samplers``, ``evaluate_kernels``: methods on the test clips.

Reads the rig's test poses and animator controls (``<paths.data>/<rig>/poses/test.parquet``,
``corpus/{test,train}.parquet``) and its fitted mappings (``<paths.models>/<rig>/<model id>/``);
writes a metrics JSON per run into ``<paths.metrics>/<rig>/<set>/``, its per-frame CSV into
``<paths.metrics>/<rig>/per_frame/<set>/`` and,
with ``evaluate.log_to_mlflow``, a parent MLflow run with a child run per method. The methods
are the ``method`` group (conf/method/*.yaml); the work is :mod:`rigmap.evaluation`'s, shared
with ``rigmap evaluate``.

    python pipelines/evaluate.py rig=quadruped evaluate.set=methods   # metrics/<rig>/methods/
    python pipelines/evaluate.py rig=quadruped evaluate.set=samplers  # metrics/<rig>/samplers/
    python pipelines/evaluate.py rig=quadruped evaluate.set=kernels   # metrics/<rig>/kernels/
"""

from __future__ import annotations

from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from rigmap.app.evaluate import evaluate_from_config
from rigmap.app.stage import run_stage


def run(cfg: DictConfig, *, experiment: str | None = None) -> list[Path]:
    """The evaluation ``cfg`` describes; ``experiment`` defaults to Hydra's choice, if any."""
    if experiment is None and HydraConfig.initialized():
        experiment = HydraConfig.get().runtime.choices.get("experiment")
    return evaluate_from_config(OmegaConf.to_container(cfg, resolve=True), experiment=experiment)


if __name__ == "__main__":
    run_stage(run)
