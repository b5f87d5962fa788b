"""The evaluate job from its composed config: one call for ``pipelines/evaluate.py`` and the CLI.

The config arrives as a plain, resolved mapping (``OmegaConf.to_container(cfg,
resolve=True)``), never a ``DictConfig``: the rig, the methods (``method.<name>``, built
from their ``_target_`` by :func:`method_catalog`), the paths, the settings and the tracking
group become plain objects here, and :func:`rigmap.evaluation.evaluate.evaluate` does the work.
"""

from __future__ import annotations

from collections.abc import Mapping
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path
from typing import Any

from rigmap.app.objects import kernel_name, sampler_name
from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.evaluate import EvaluationSettings, evaluate
from rigmap.evaluation.method import method_catalog
from rigmap.rigs import use_executor
from rigmap.store import Layout
from rigmap.store.layout import REPLICATED_REGRESSORS

__all__ = ["evaluate_command", "evaluate_from_config", "method_catalog", "rig_from_mapping"]


def evaluate_from_config(config: Mapping[str, Any], *, experiment: str | None = None) -> list[Path]:
    """Run the evaluation ``config`` describes; ``experiment`` is the experiment group's choice."""
    if not isinstance(config, Mapping) or type(config).__module__.startswith("omegaconf"):
        raise TypeError(
            "evaluate_from_config: expected a plain mapping (OmegaConf.to_container(cfg, "
            f"resolve=True)), got {type(config).__name__}"
        )
    for group in ("rig", "method", "paths", "evaluate", "sampler", "kernel", "budget"):
        if group not in config:
            raise EvaluationSetupError(f"evaluate stage config: no {group!r} group")
    settings = EvaluationSettings.from_mapping(config["evaluate"])
    catalog = method_catalog(config["method"])
    layout = Layout.from_paths(config["paths"], config.get("replicate"))
    if layout.replicate is not None:
        settings = replace(settings, methods=replicated_methods(settings.methods, catalog))
    rig = rig_from_mapping(config["rig"])
    if config.get("executor") is not None:
        use_executor(rig, dict(config["executor"]))
    log = None
    if settings.log_to_mlflow:
        from rigmap.evaluation.mlflow_runs import EvaluationLog

        log = EvaluationLog.start(
            config.get("tracking") or {},
            rig.name,
            settings.set,
            config,
            log_models=settings.log_models,
        )
    with log if log is not None else nullcontext():
        return evaluate(
            rig,
            catalog,
            layout,
            settings,
            nn_sampler=sampler_name(config["sampler"]),
            gpr_kernel=kernel_name(config["kernel"]),
            record={"experiment": experiment, "budget": dict(config["budget"])},
            log=log,
        )


def replicated_methods(methods, catalog) -> tuple[str, ...]:
    """Of ``methods``, those whose guess is a network a replicate seed re-trains: only they can
    differ from seed 0's rows, so a replicate run scores nothing else (whatever list a rig's
    ``_overrides_`` gives); an error naming the option when none is left. A name the
    catalogue lacks is kept, so the evaluation refuses it as it would without a replicate."""
    kept = tuple(
        name
        for name in methods
        if name not in catalog or catalog[name].regressor in REPLICATED_REGRESSORS
    )
    if not kept:
        raise EvaluationSetupError(
            f"evaluate.methods: a replicate seed scores only methods guessed by a re-trained "
            f"network ({', '.join(REPLICATED_REGRESSORS)}); none in {list(methods)}"
        )
    return kept


def evaluate_command(overrides: list[str], config_dir=None) -> list[Path]:
    """``rigmap evaluate``: ``conf/`` composed with ``overrides`` and evaluated as the stage
    does, the experiment group's choice recorded."""
    from omegaconf import OmegaConf

    from rigmap.app.config import compose_config

    cfg = compose_config(overrides, config_dir, with_hydra=True)
    experiment = cfg.hydra.runtime.choices.get("experiment")
    stage = OmegaConf.masked_copy(cfg, [key for key in cfg if key != "hydra"])
    return evaluate_from_config(OmegaConf.to_container(stage, resolve=True), experiment=experiment)


def rig_from_mapping(rig_config: Mapping[str, Any]) -> Any:
    """The rig the ``rig`` group names (its ``corpus`` options are not the factory's)."""
    from rigmap.rigs import load

    options = dict(rig_config)
    options.pop("corpus", None)
    return load(options)


def lead_view_link(overrides, config_dir, rig: str, view: str, ui: str | None) -> str:
    """``rigmap tracking url``: the link to ``rig``'s saved runs view ``view`` in the MLflow
    UI of the tracking store ``conf/`` (with ``overrides``) names."""
    from omegaconf import OmegaConf

    from rigmap.app.config import compose_config
    from rigmap.tracking import Tracker, lead_view_url, view_id

    cfg = compose_config(list(overrides), config_dir)
    tracker = Tracker.from_config(OmegaConf.to_container(cfg.tracking, resolve=True))
    return lead_view_url(tracker, rig, view_id(view), ui_url=ui)
