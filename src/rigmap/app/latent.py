"""The latent stage from a composed config: the steps, the rig, the layout, MLflow.

``run_steps(cfg)`` is what ``pipelines/latent.py`` calls (the four steps in order, or the one
``cfg.latent_step`` names), ``run_step(cfg)`` what ``rigmap synth fit|match`` calls:
``cfg.latent_step`` (fit, match, synthesize, evaluate) picks the function of
:mod:`rigmap.latent.steps`; with ``latent.log_to_mlflow`` each step is a parent run
``latent-<step>`` in the rig's experiment (:mod:`rigmap.tracking`) with the latent
config as params, the step's numbers as metrics and its JSON as an artifact.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from omegaconf import OmegaConf

from rigmap.latent import steps
from rigmap.latent.errors import LatentInputError
from rigmap.store.layout import LATENT

STEPS = ("fit", "match", "synthesize", "evaluate")


def step_of(cfg) -> str:
    step = cfg.get("latent_step")
    if step not in STEPS:
        raise LatentInputError(f"+latent_step: expected one of {STEPS}, got {step!r}")
    return str(step)


def latent_config(cfg) -> dict:
    if "latent" not in cfg:
        raise LatentInputError("no latent config: conf/latent/default.yaml is not composed")
    config = OmegaConf.to_container(cfg.latent, resolve=True)
    config["seed"] = int(cfg.get("seed", 0))
    return config


def fitted_models_config(overrides, config_dir, compose_config):
    """The composed config whose models are your own ``rigmap synth fit`` and ``match``'s
    (under outputs/) when they hold the rig's, else the pipeline's (``models/``), unless
    ``paths.models=DIR`` names them: only ``--out`` is ever written."""
    from rigmap.store import Layout
    from rigmap.user_outputs import user_paths

    cfg = compose_config(list(overrides), config_dir)
    own = user_paths(overrides, keys=("models",))
    if own and Layout(models=Layout.user_root("models")).latent_fit(str(cfg.rig.name)).is_dir():
        cfg = compose_config([*own, *overrides], config_dir)
    return cfg


def run_steps(cfg) -> list[Path]:
    """Every step in order (the DVC stage: they share their inputs), or ``+latent_step``'s."""
    if cfg.get("latent_step") is not None:
        return [run_step(cfg)]
    from rigmap.app.inputs import layout_of, rig_from_config

    config, layout, rig = latent_config(cfg), layout_of(cfg), rig_from_config(cfg.rig)
    return [_run(cfg, step, config, rig, layout) for step in STEPS]


def run_step(cfg) -> Path:
    from rigmap.app.inputs import layout_of, rig_from_config

    step = step_of(cfg)
    return _run(cfg, step, latent_config(cfg), rig_from_config(cfg.rig), layout_of(cfg))


def _run(cfg, step: str, config: dict, rig, layout) -> Path:
    started = time.perf_counter()
    path = getattr(steps, f"run_{step}")(config, rig, layout)
    seconds = time.perf_counter() - started
    print(f"latent_{step} ({rig.name}): {path} in {seconds:.1f} s", flush=True)
    if config.get("log_to_mlflow", False) and step in config.get("mlflow_steps", STEPS):
        log_step(cfg, rig.name, step, config, path, seconds, layout=layout)
    return path


def step_metrics(step: str, record: dict, seconds: float) -> dict[str, float]:
    """The numbers a step's MLflow run shows (flat, finite)."""
    metrics = {"seconds": seconds}
    if step == "fit":
        for label, info in record.items():
            metrics[f"{label}.pca_dims"] = info["pca_dims"]
            metrics[f"{label}.fit_s"] = info["fit_s"]
            metrics[f"{label}.objective_end"] = info["objective_end"]
    elif step == "match":
        for row in record["pairs"]:
            metrics[f"points.{row['pair']}"] = row["points"]
    elif step == "synthesize":
        for run, rows in record.items():
            metrics[f"{run}.frames"] = sum(r["frames"] for r in rows)
            metrics[f"{run}.success_rate"] = sum(r["success"] for r in rows) / max(1, len(rows))
    else:
        for q, value in record["heldout_surface_rms_cm_by_latent_dim"].items():
            metrics[f"heldout_surface_rms_cm.q{q}"] = value
        for key, value in record["smoothness"].items():
            metrics[f"smoothness.{key}"] = value
        for kind, row in record["suites"].items():
            metrics[f"suite.{kind}.success_rate"] = row["success_rate"]
        metrics["matching_points_median"] = record["matching_points"]["median"]
    return {k: float(v) for k, v in metrics.items() if v is not None}


def earlier_records(config: dict, rig: str, step: str, layout) -> dict[str, Path]:
    """The JSON records of the steps before ``step`` that log no run of their own
    (``latent.mlflow_steps``), so the run that is logged carries them too."""
    own = set(config.get("mlflow_steps", STEPS))
    paths = {
        "fit": layout.latent_fit(rig) / "fit.json",
        "match": layout.latent_match(rig) / "match.json",
        "synthesize": layout.app_data(rig, LATENT) / "log.json",
    }
    before = STEPS[: STEPS.index(step)]
    return {s: paths[s] for s in before if s not in own and paths[s].is_file()}


def log_step(cfg, rig: str, step: str, config: dict, path: Path, seconds: float, *, layout=None):
    """The step's parent run ``latent-<step>`` (metrics of earlier unlogged steps
    prefixed with their step's name, their JSON beside the step's own)."""
    from mlflow.entities import Metric

    from rigmap.tracking import Tracker, start_parent_run
    from rigmap.tracking.keys import safe_name

    tracker = Tracker.from_config(OmegaConf.to_container(cfg.tracking, resolve=True))
    records = {step: Path(path)}
    if layout is not None:
        records.update(earlier_records(config, rig, step, layout))
    values: dict[str, float] = {}
    for name, file in records.items():
        numbers = step_metrics(name, json.loads(file.read_text()), seconds if name == step else 0)
        prefix = "" if name == step else f"{name}."
        values.update({prefix + k: v for k, v in numbers.items() if name == step or k != "seconds"})
    with start_parent_run(
        tracker,
        rig,
        name=f"latent-{step}",
        config={"latent": config},
        tags={"stage": f"latent_{step}", "kind": "latent"},
    ) as parent:
        now = int(time.time() * 1000)
        metrics = [Metric(safe_name(k), v, now, 0) for k, v in values.items()]
        for start in range(0, len(metrics), 1000):
            tracker.client.log_batch(parent.run_id, metrics=metrics[start : start + 1000])
        for name, file in records.items():
            tracker.client.log_artifact(parent.run_id, str(file), artifact_path=name)
    print(f"MLflow: {tracker.uri}, run {parent.run_id}", flush=True)
    return parent.run_id
