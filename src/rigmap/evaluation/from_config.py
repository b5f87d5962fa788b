"""The evaluate stage from its composed config: one call for ``pipelines/evaluate.py`` and the CLI.

The config arrives as a plain, resolved mapping (``OmegaConf.to_container(cfg,
resolve=True)``), never a ``DictConfig``: the rig, the methods (``method.<name>``,
built by ``hydra.utils.instantiate``), the paths, the settings and the tracking group
become plain objects here, and :func:`rigmap.evaluation.evaluate.evaluate` does the work.
"""

from __future__ import annotations

from collections.abc import Mapping
from contextlib import nullcontext
from pathlib import Path
from typing import Any

from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.evaluate import EvaluationSettings, evaluate
from rigmap.evaluation.method import method_catalog
from rigmap.sampling import sampler_name
from rigmap.store import Layout


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
    rig = rig_from_mapping(config["rig"])
    if config.get("executor") is not None:
        from rigmap.stage.inputs import use_executor

        use_executor(rig, dict(config["executor"]))
    log = None
    if settings.log_to_mlflow:
        from rigmap.evaluation.mlflow_runs import EvaluationLog

        log = EvaluationLog.start(
            config.get("tracking") or {}, rig.name, settings.set, config,
            log_models=settings.log_models,
        )  # fmt: skip
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


def rig_from_mapping(rig_config: Mapping[str, Any]) -> Any:
    """The rig the ``rig`` group names (its ``corpus`` options are not the factory's)."""
    from rigmap.rigs import load

    options = dict(rig_config)
    options.pop("corpus", None)
    return load(options)


def kernel_name(kernel_config: Mapping[str, Any]) -> str:
    """The kernel's label in model ids (``multiquadric``, ``multiquadric_plus_linear`` …)."""
    import hydra.utils

    return str(hydra.utils.instantiate(dict(kernel_config)).label)
