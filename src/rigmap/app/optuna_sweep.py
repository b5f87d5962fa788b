"""What rigmap adds to the maintained Optuna sweeper (``hydra/sweeper=optuna``, the
hydra-optuna-sweeper plugin): resumable studies and one MLflow parent run per study.

:class:`OptunaSweepCallback` is a Hydra callback (``hydra.callbacks`` in conf/tune.yaml).
Hydra calls ``on_multirun_start`` before it builds the sweeper, so the callback can:

- fail the trials a killed sweep left RUNNING (nothing else ever will: the plugin asks and
  tells trials itself, without Optuna's heartbeat) and enqueue their parameters again;
- with ``resume`` (the default), turn ``hydra.sweeper.n_trials`` into the number of COMPLETE
  trials the study must reach: the plugin runs ``n_trials`` *more* trials on every call, so
  the callback lowers it to what is missing, and rerunning a killed sweep's command ends
  with exactly ``n_trials`` complete trials;
- add the number of trials the study holds to a seeded sampler's seed, so a resumed sweep
  does not draw the points of the first one again;
- open the study's MLflow parent run (or reopen it: its id is the study's user attribute
  ``mlflow_parent_run_id``) and hand its id to every job as a fixed sweeper parameter
  ``+optuna.parent_run_id``, so a job on another process or machine (submitit, Ray) logs
  its child run under it.

``on_multirun_end`` names each child run after its Optuna trial, logs the best trial on the
parent, adds the parent's id to ``optimization_results.yaml`` and finishes the parent run.
One sweep process per study at a time: a second one would see the first one's running
trials as stale. A sweep stopped by an error or a kill leaves its parent run RUNNING (Hydra
has no multirun-failed hook); the next run of the same study reopens and finishes it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

log = logging.getLogger(__name__)

PARENT_ATTR = "mlflow_parent_run_id"
TRIAL_TAG = "optuna_trial"
STUDY_TAG = "optuna_study"
PARENT_PARAM = "+optuna.parent_run_id"
STUDY_PARAM = "+optuna.study"


def _sweeper_option(sweeper: DictConfig, key: str) -> Any:
    value = sweeper.get(key)
    if value is None or value == "":
        raise ValueError(f"hydra.sweeper.{key}: a resumable Optuna sweep needs it set")
    return value


def _directions(direction: Any) -> list[str]:
    """``hydra.sweeper.direction`` (a name or a list of names) as Optuna's direction names."""
    names = list(direction) if OmegaConf.is_list(direction) else [direction]
    return [getattr(name, "name", str(name)) for name in names]


def open_study(sweeper: DictConfig):
    """The sweep's study, created if new (an SQLite file's folder too)."""
    import optuna

    storage = str(_sweeper_option(sweeper, "storage"))
    if storage.startswith("sqlite:///"):
        Path(storage.removeprefix("sqlite:///")).parent.mkdir(parents=True, exist_ok=True)
    return optuna.create_study(
        study_name=str(_sweeper_option(sweeper, "study_name")),
        storage=storage,
        directions=_directions(sweeper.get("direction", "minimize")),
        load_if_exists=True,
    )


def fail_stale_trials(study) -> list[int]:
    """Trials left RUNNING by a killed sweep: FAIL, their parameters enqueued again."""
    import optuna

    running = (optuna.trial.TrialState.RUNNING,)
    stale = study.get_trials(deepcopy=False, states=running)
    for trial in stale:
        study.tell(trial.number, state=optuna.trial.TrialState.FAIL)
        study.enqueue_trial(trial.params, skip_if_exists=False)
        log.info(f"optuna: trial {trial.number} was cut off by a kill: failed, asked again")
    return [trial.number for trial in stale]


def complete_trials(study) -> list:
    import optuna

    return study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))


class OptunaSweepCallback(Callback):
    """Resume and MLflow bookkeeping around the maintained Optuna sweeper (module docstring)."""

    def __init__(self, rig: str, resume: bool = True) -> None:
        if not isinstance(resume, bool):
            raise ValueError(f"hydra.callbacks.optuna_mlflow.resume: {resume!r} is not true/false")
        self.rig = str(rig)
        self.resume = resume
        self.parent_id: str | None = None

    def _tracker(self, config: DictConfig):
        from rigmap.tracking.runs import Tracker

        tracking = config.get("tracking")
        plain = OmegaConf.to_container(tracking, resolve=True) if tracking is not None else {}
        return Tracker.from_config(plain)

    def _parent_run(self, study, tracker, sweeper: DictConfig, n_trials: int) -> str:
        from rigmap.tracking.runs import start_parent_run

        parent_id = study.user_attrs.get(PARENT_ATTR)
        if parent_id is not None:
            tracker.client.update_run(parent_id, status="RUNNING")  # resumed
            return str(parent_id)
        config = {
            "study": study.study_name,
            "storage": str(sweeper.storage),
            "n_trials": n_trials,
            "direction": ",".join(_directions(sweeper.get("direction", "minimize"))),
            "space": OmegaConf.to_container(sweeper.get("params") or {}, resolve=True),
        }
        parent = start_parent_run(
            tracker,
            self.rig,
            name=f"optuna-{study.study_name}",
            config=config,
            tags={"kind": "optuna_sweep", STUDY_TAG: study.study_name},
        )
        if parent._monitor is not None:  # the parent outlives this call: ended at the sweep's end
            parent._monitor.finish()
            parent._monitor = None
        study.set_user_attr(PARENT_ATTR, parent.run_id)
        return parent.run_id

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        sweeper = config.hydra.sweeper
        n_trials = int(sweeper.n_trials)
        if n_trials < 0:
            raise ValueError(f"hydra.sweeper.n_trials: {n_trials} is negative")
        study = open_study(sweeper)
        fail_stale_trials(study)
        tracker = self._tracker(config)
        self.parent_id = self._parent_run(study, tracker, sweeper, n_trials)
        with read_write(config.hydra), open_dict(config.hydra.sweeper):
            if self.resume:
                done = len(complete_trials(study))
                sweeper.n_trials = max(n_trials - done, 0)
                log.info(f"optuna: {done} of {n_trials} trials complete; running the rest")
            _reseed(sweeper, len(study.trials))
            if sweeper.get("params") is None:
                sweeper.params = {}
            with open_dict(sweeper.params):
                # quoted: a run id of digits and one "e" would otherwise parse as a float
                sweeper.params[PARENT_PARAM] = f"'{self.parent_id}'"
                sweeper.params[STUDY_PARAM] = f"'{study.study_name}'"

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        if self.parent_id is None:
            return
        study = open_study(config.hydra.sweeper)
        client = self._tracker(config).client
        name_children(client, self.parent_id, complete_trials(study))
        if len(study.directions) == 1 and complete_trials(study):
            best = study.best_trial
            client.log_metric(self.parent_id, "best_value", float(best.value))
            for key, value in best.params.items():
                client.set_tag(self.parent_id, f"best.{key}", str(value))
            client.set_tag(self.parent_id, "best_trial", str(best.number))
            _add_to_results(Path(config.hydra.sweep.dir), best.number, self.parent_id)
        client.set_terminated(self.parent_id, status="FINISHED")


def _reseed(sweeper: DictConfig, n_asked: int) -> None:
    """A seeded sampler in a new process draws its points again from the start, so a resumed
    study's sampler seed is the configured one plus the trials the study already holds."""
    sampler = sweeper.get("sampler")
    if n_asked and sampler is not None and sampler.get("seed") is not None:
        with open_dict(sampler):
            sampler.seed = int(sampler.seed) + n_asked


def _add_to_results(sweep_dir: Path, best_trial: int, parent_id: str) -> None:
    """The plugin's ``optimization_results.yaml`` with the best trial's number and the parent."""
    from rigmap.store import write_text_atomic

    path = sweep_dir / "optimization_results.yaml"
    if not path.is_file():
        return
    results = OmegaConf.load(path)
    results.best_trial = best_trial
    results[PARENT_ATTR] = parent_id
    write_text_atomic(path, OmegaConf.to_yaml(results))


def name_children(client, parent_id: str, trials: list) -> int:
    """Tag each not yet named child run with the one complete trial whose parameters it
    logged (a job does not know its trial's number); returns how many were named."""
    parent = client.get_run(parent_id)
    runs = client.search_runs(
        [parent.info.experiment_id], filter_string=f"tags.mlflow.parentRunId = '{parent_id}'"
    )
    named = 0
    for run in runs:
        if TRIAL_TAG in run.data.tags:
            continue
        matches = [t for t in trials if _same_params(t.params, run.data.params)]
        if len(matches) != 1:
            continue
        client.set_tag(run.info.run_id, TRIAL_TAG, str(matches[0].number))
        client.set_tag(run.info.run_id, "mlflow.runName", f"trial-{matches[0].number}")
        named += 1
    return named


def _same_params(trial_params: Mapping[str, Any], logged: Mapping[str, str]) -> bool:
    return bool(trial_params) and all(
        logged.get(key) == str(value) for key, value in trial_params.items()
    )
