"""The sweeper's structured config, stored as ``hydra/sweeper=optuna``."""

from dataclasses import dataclass, field
from typing import Any

from hydra.core.config_store import ConfigStore


@dataclass
class OptunaSweeperConf:
    _target_: str = "hydra_plugins.rigmap_optuna_sweeper.optuna_sweeper.OptunaSweeper"
    study_name: str = "rigmap"
    # SQLite file (or any optuna RDB URL): a killed sweep resumes from it (load_if_exists)
    storage: str = "sqlite:///optuna.db"
    direction: str = "minimize"
    n_trials: int = 12  # COMPLETE trials the study must reach (earlier runs count)
    n_jobs: int = 1  # trials asked at once and handed to the launcher together
    seed: int = 0  # TPE sampler seed
    # search space: {override key: {type: float|int|categorical, low, high, log, step, choices}}
    params: dict[str, Any] = field(default_factory=dict)
    # MLflow: one parent run per study (its id kept in the study), a child per trial
    mlflow_rig: str = "quadruped"


ConfigStore.instance().store(
    group="hydra/sweeper", name="optuna", node=OptunaSweeperConf, provider="rigmap"
)
