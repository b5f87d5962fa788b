"""An Optuna sweeper for Hydra on current Optuna, with one MLflow parent run per study.

Why not hydra-optuna-sweeper: it pins optuna 2.10, whose storage fails on SQLAlchemy 2 —
which MLflow 3 needs. This one asks Optuna for ``n_jobs`` trials at a time, hands their
overrides to the configured Hydra launcher (basic, joblib, submitit), and tells Optuna each
job's return value. The study lives in ``storage`` (SQLite by default) with
``load_if_exists=True``: run the same command after a kill and it goes on to ``n_trials``
complete trials. A trial left RUNNING by a killed sweep is marked FAIL, its MLflow child run
deleted, and its parameters enqueued again, so the study ends with exactly ``n_trials``
complete trials and the parent run with one finished child each.

The MLflow parent run is created once per study (its id kept as the study's user attribute
``mlflow_parent_run_id``) and passed to every job explicitly, as overrides
``+optuna.parent_run_id=… +optuna.trial=… +optuna.study=…``, so a job in another process
or on another machine (submitit/Slurm) nests its child run under it.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from hydra.core.plugins import Plugins
from hydra.plugins.sweeper import Sweeper
from omegaconf import DictConfig, OmegaConf

log = logging.getLogger(__name__)

PARENT_ATTR = "mlflow_parent_run_id"
TRIAL_TAG = "optuna_trial"
STUDY_TAG = "optuna_study"


def distribution(key: str, spec: Any):
    """An Optuna distribution from ``{type: float|int|categorical, low, high, log, step}``."""
    import optuna

    spec = dict(spec)
    kind = spec.pop("type", None)
    try:
        if kind == "float":
            return optuna.distributions.FloatDistribution(
                float(spec["low"]), float(spec["high"]), log=bool(spec.get("log", False)),
                step=None if spec.get("step") is None else float(spec["step"]),
            )  # fmt: skip
        if kind == "int":
            return optuna.distributions.IntDistribution(
                int(spec["low"]), int(spec["high"]), log=bool(spec.get("log", False)),
                step=int(spec.get("step") or 1),
            )  # fmt: skip
        if kind == "categorical":
            return optuna.distributions.CategoricalDistribution(list(spec["choices"]))
    except KeyError as missing:
        raise ValueError(f"optuna sweeper: parameter {key!r} needs {missing} ({kind})") from None
    raise ValueError(
        f"optuna sweeper: parameter {key!r} has type {kind!r}; expected float, int or categorical"
    )


class OptunaSweeper(Sweeper):
    def __init__(
        self,
        study_name: str,
        storage: str,
        direction: str,
        n_trials: int,
        n_jobs: int,
        seed: int,
        params: Any,
        mlflow_rig: str,
    ):
        if int(n_trials) < 1 or int(n_jobs) < 1:
            raise ValueError("optuna sweeper: n_trials and n_jobs must be >= 1")
        params = OmegaConf.to_container(params, resolve=True) if isinstance(params, DictConfig) \
            else dict(params or {})  # fmt: skip
        if not params:
            raise ValueError("optuna sweeper: hydra.sweeper.params is empty: nothing to search")
        self.study_name = study_name
        self.storage = storage
        self.direction = direction
        self.n_trials = int(n_trials)
        self.n_jobs = int(n_jobs)
        self.seed = int(seed)
        self.space = {k: distribution(k, v) for k, v in params.items()}
        self.mlflow_rig = mlflow_rig
        self.job_idx = 0

    def setup(self, *, hydra_context, task_function, config: DictConfig) -> None:
        self.config = config
        self.hydra_context = hydra_context
        self.launcher = Plugins.instance().instantiate_launcher(
            config=config, hydra_context=hydra_context, task_function=task_function
        )

    # ------------------------------------------------------------------ the study
    def _study(self):
        import optuna

        if self.storage.startswith("sqlite:///"):
            Path(self.storage.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
        return optuna.create_study(
            study_name=self.study_name,
            storage=self.storage,
            direction=self.direction,
            sampler=optuna.samplers.TPESampler(seed=self.seed),
            load_if_exists=True,
        )

    def _tracker(self):
        from rigmap.tracking import Tracker

        tracking = self.config.get("tracking")
        plain = OmegaConf.to_container(tracking, resolve=True) if tracking is not None else {}
        return Tracker.from_config(plain)

    def _parent_run(self, study, tracker) -> str:
        from rigmap.tracking import start_parent_run

        parent_id = study.user_attrs.get(PARENT_ATTR)
        if parent_id is not None:
            tracker.client.update_run(parent_id, status="RUNNING")  # resumed
            return parent_id
        parent = start_parent_run(
            tracker, self.mlflow_rig, name=f"optuna-{self.study_name}",
            config={"study": self.study_name, "storage": self.storage, "n_trials": self.n_trials,
                    "direction": self.direction,
                    "space": {k: repr(v) for k, v in self.space.items()}},
            tags={"kind": "optuna_sweep", STUDY_TAG: self.study_name},
        )  # fmt: skip
        if parent._monitor is not None:  # the sweeper ends the run itself, later
            parent._monitor.finish()
            parent._monitor = None
        study.set_user_attr(PARENT_ATTR, parent.run_id)
        return parent.run_id

    def _recover(self, study, tracker, parent_id: str) -> None:
        """Trials a killed sweep left RUNNING: FAIL, child run deleted, parameters again."""
        import optuna

        stale = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,))
        for trial in stale:
            study.tell(trial.number, state=optuna.trial.TrialState.FAIL)
            study.enqueue_trial(trial.params, skip_if_exists=False)
            runs = tracker.client.search_runs(
                [tracker.experiment_id(self.mlflow_rig)],
                filter_string=f"tags.mlflow.parentRunId = '{parent_id}' and "
                f"tags.{TRIAL_TAG} = '{trial.number}'",
            )
            for run in runs:
                tracker.client.delete_run(run.info.run_id)
            log.info(f"optuna: trial {trial.number} was cut off by a kill: retried")

    def sweep(self, arguments: list[str]) -> list:
        import optuna

        study = self._study()
        tracker = self._tracker()
        parent_id = self._parent_run(study, tracker)
        self._recover(study, tracker, parent_id)
        complete = optuna.trial.TrialState.COMPLETE
        returns = []
        try:
            while (done := len(study.get_trials(states=(complete,)))) < self.n_trials:
                trials = [
                    study.ask(self.space) for _ in range(min(self.n_jobs, self.n_trials - done))
                ]
                overrides = [
                    (
                        *(f"{k}={v}" for k, v in trial.params.items()),
                        f"+optuna.parent_run_id={parent_id}",
                        f"+optuna.trial={trial.number}",
                        f"+optuna.study={self.study_name}",
                        *arguments,
                    )
                    for trial in trials
                ]
                results = self.launcher.launch(overrides, initial_job_idx=self.job_idx)
                self.job_idx += len(results)
                for trial, result in zip(trials, results, strict=True):
                    try:
                        value = float(result.return_value)  # re-raises a failed job's error
                    except Exception as error:
                        log.warning(f"optuna: trial {trial.number} failed: {error}")
                        study.tell(trial, state=optuna.trial.TrialState.FAIL)
                        continue
                    study.tell(trial, value)
                returns.append(results)
        except BaseException:
            tracker.client.set_terminated(parent_id, status="KILLED")
            raise
        best = study.best_trial
        client = tracker.client
        client.log_metric(parent_id, "best_value", float(best.value))
        for key, value in best.params.items():
            client.set_tag(parent_id, f"best.{key}", str(value))
        client.set_tag(parent_id, "best_trial", str(best.number))
        client.set_terminated(parent_id, status="FINISHED")
        out = Path(self.config.hydra.sweep.dir)
        out.mkdir(parents=True, exist_ok=True)
        OmegaConf.save(
            OmegaConf.create({"name": "optuna", "best_params": best.params,
                              "best_value": float(best.value), "best_trial": best.number,
                              "mlflow_parent_run_id": parent_id}),
            out / "optimization_results.yaml",
        )  # fmt: skip
        log.info(f"optuna: best {best.value:.6g} at trial {best.number}: {best.params}")
        return returns
