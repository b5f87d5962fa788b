"""A hyperparameter trial of the network (conf/tune.yaml); ``--multirun`` sweeps it with Optuna.

    python pipelines/tune.py --multirun                         # 12 Optuna trials (resumable)
    python pipelines/tune.py --multirun hydra/launcher=joblib   # trials in parallel processes
    python pipelines/tune.py regressor.hidden=64                # one trial, no sweep

Returns the validation joint error (cm²), which the sweeper minimises; not a DVC stage.
"""

from __future__ import annotations

from omegaconf import DictConfig, OmegaConf

from rigmap.app.inputs import rig_from_config
from rigmap.app.objects import instantiate_as
from rigmap.app.stage import run_stage


def run(cfg: DictConfig) -> float:
    from rigmap.regression.base import Regressor
    from rigmap.tune import log_trial, run_trial

    rig = rig_from_config(cfg.rig)
    regressor = instantiate_as(cfg.regressor, Regressor, "regressor", ValueError)
    scores = run_trial(rig, regressor, OmegaConf.to_container(cfg.tune, resolve=True))
    print(f"trial: joint error {scores['joint_error']:.4g} cm², fit {scores['fit_seconds']:.1f} s")
    sweep = cfg.get("optuna")
    if sweep is not None and sweep.get("parent_run_id"):
        params = {k: OmegaConf.select(cfg, k) for k in cfg.tune.logged_params}
        log_trial(OmegaConf.to_container(cfg.tracking, resolve=True), sweep, params, scores)
    return scores["joint_error"]


if __name__ == "__main__":
    run_stage(run, config_name="tune")
