"""One trial of a hyperparameter sweep: fit the network on a rig's poses, score it held out.

``pipelines/tune.py`` runs it as a Hydra app; ``--multirun`` with ``hydra/sweeper=optuna``
(the maintained hydra-optuna-sweeper, conf/tune.yaml) makes it an Optuna study. A trial
draws its own seeded training and validation poses from the rig (no DVC data needed, so a
Slurm node needs only the code), fits ``regressor`` through
:class:`~rigmap.regression.mapping.InverseMapping` as the fit stage does, and returns the
validation joint error (mean squared joint distance, cm²: what the sweep minimises). With
``optuna.parent_run_id`` set (the sweep's callback,
:class:`rigmap.app.optuna_sweep.OptunaSweepCallback`, passes it) the trial is logged
as an MLflow child run of the study's parent run, with its parameters and score.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from rigmap.error_measures import joint_error
from rigmap.regression.features import inverse_features
from rigmap.regression.mapping import InverseMapping
from rigmap.regression.placement import find_placement


def used_draws(rig, n: int, seed: int, spread: float) -> np.ndarray:
    """Used controls ``spread`` of the way from their defaults into their soft ranges."""
    rng = np.random.default_rng(seed)
    used = rig.controls.used_indices
    defaults = rig.controls.defaults[used]
    lo, hi = rig.controls.lower[used], rig.controls.upper[used]
    return (1 - spread) * defaults + spread * rng.uniform(lo, hi, size=(n, len(used)))


def features(rig, Y_used: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pose = rig.pose(rig.expand_used(Y_used))
    X = inverse_features(
        pose.positions, pose.cog, pose.cog_rotation, n_joints=rig.n_joints, where="tune"
    )
    return X, np.asarray(pose.positions)


def run_trial(rig, regressor, settings: Mapping[str, Any]) -> dict[str, float]:
    """Fit ``regressor`` on ``settings.train_rows`` draws; errors on ``settings.val_rows``."""
    seed = int(settings.get("seed", 0))
    spread = float(settings.get("spread", 0.3))
    Y_train = used_draws(rig, int(settings["train_rows"]), seed, spread)
    Y_val = used_draws(rig, int(settings["val_rows"]), seed + 1, spread)
    X_train, _ = features(rig, Y_train)
    X_val, joints_val = features(rig, Y_val)
    defaults = rig.controls.defaults[rig.controls.used_indices]
    placement = find_placement(rig, np.concatenate([defaults[None], Y_train[:4]]))
    options: dict[str, Any] = {"rig_name": rig.name, "control_names": list(rig.used_controls)}
    options.update(regressor.rig_fit_options(rig=rig, placement=placement))
    started = time.perf_counter()
    mapping = InverseMapping(regressor, placement).fit(X_train, Y_train, **options)
    fit_seconds = time.perf_counter() - started
    predicted = mapping.predict(X_val)
    posed = rig.evaluate(rig.expand_used(predicted))
    return {
        "joint_error": float(joint_error(np.asarray(posed), joints_val).mean),
        "control_rmse": float(np.sqrt(np.mean((predicted - Y_val) ** 2))),
        "fit_seconds": fit_seconds,
    }


def log_trial(tracking: Mapping | None, sweep: Mapping, params: Mapping, scores: Mapping) -> str:
    """The trial as a child of the sweep's parent run (``sweep.parent_run_id``); its run id."""
    from mlflow.entities import RunStatus
    from mlflow.utils.mlflow_tags import MLFLOW_PARENT_RUN_ID

    from rigmap.tracking import Tracker

    tracker = Tracker.from_config(dict(tracking or {}))
    parent = tracker.client.get_run(str(sweep["parent_run_id"]))
    tags = {
        MLFLOW_PARENT_RUN_ID: parent.info.run_id,
        "optuna_study": str(sweep.get("study", "")),
        "kind": "optuna_trial",
    }
    trial = sweep.get("trial")
    if trial is not None:  # else the sweep's callback names the run after the sweep
        tags["optuna_trial"] = str(trial)
    run = tracker.client.create_run(
        parent.info.experiment_id, run_name=f"trial-{'?' if trial is None else trial}", tags=tags
    )
    run_id = run.info.run_id
    for key, value in params.items():
        tracker.client.log_param(run_id, key, value)
    for key, value in scores.items():
        tracker.client.log_metric(run_id, key, float(value))
    tracker.client.set_terminated(run_id, RunStatus.to_string(RunStatus.FINISHED))
    return run_id
