"""DVC stage ``fit``: an inverse rig mapping fitted on a rig's training data.

Reads ``<paths.data>/<rig>/corpus/train.parquet`` and ``poses/train.parquet`` (plus
``samples/<sampler>.npz`` unless the sampler is ``none``) and writes
``<paths.models>/<rig>/<regressor>-<sampler>-<kernel>/`` atomically: the model files,
``fit.json`` (rows, seconds, feature layout, training error, the resolved config) and,
for a multiquadric GPR, the learned Jacobian in ``learned_jacobian/``. The logic lives
in :mod:`rigmap.regression.fitting`, called through :mod:`rigmap.app.fit` as ``rigmap fit``
does.

    python pipelines/fit.py rig=quadruped regressor=nn sampler=pca_gaussian
    python pipelines/fit.py rig=quadruped regressor=gpr sampler=none kernel=multiquadric
"""

from __future__ import annotations

from omegaconf import DictConfig

from rigmap.app.fit import fit_from_config
from rigmap.app.stage import run_stage
from rigmap.regression.fitting import FitResult


def run(cfg: DictConfig) -> FitResult:
    return fit_from_config(cfg)


if __name__ == "__main__":
    run_stage(run)
