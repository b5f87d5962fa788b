"""Experiments, parent runs and method runs: how rigmap lays its results out in MLflow.

One experiment per rig (``rigmap-<rig>``); one parent run per sweep or
pipeline run; under it one child run per (method, sampler, kernel) with the
flattened config as params, the metrics JSON as metrics (average and per
clip), tags a lead filters on, the data files it read as datasets, and the files a
person opens: the composed config, the predicted control curves, the per-frame errors
(CSV and plot).

Runs are written through an explicit ``MlflowClient``; only model logging goes
through MLflow's fluent API (the one thing it requires), pointed at the same URI.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import KW_ONLY, dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import pandas as pd
from mlflow import MlflowClient
from mlflow.entities import DatasetInput, Metric, Param, RunStatus
from mlflow.exceptions import MlflowException
from mlflow.utils.mlflow_tags import MLFLOW_PARENT_RUN_ID, MLFLOW_RUN_NAME

from rigmap.store import write_text_atomic
from rigmap.tracking import artifacts
from rigmap.tracking.champion import CHAMPION_METRIC, promote_if_better
from rigmap.tracking.keys import (
    MAX_TAG_VALUE_LENGTH,
    flatten_config,
    method_metrics,
    safe_name,
    truncate,
)
from rigmap.tracking.pyfunc_model import LoggedMapping, log_inverse_mapping
from rigmap.tracking.store import (
    DEFAULT_PROBE_TIMEOUT_S,
    DEFAULT_REQUEST_RETRIES,
    DEFAULT_REQUEST_TIMEOUT_S,
    bound_http_retries,
    check_reachable,
    is_http_uri,
    local_artifact_root,
    project_folder,
    resolve_tracking_uri,
)

EXPERIMENT_PREFIX = "rigmap"
EXPERIMENT_KIND = "custom_model_development"  # the mlflow.experimentKind tag of every experiment
_BATCH = 100  # MLflow accepts at most 100 params or tags per log_batch call


@runtime_checkable
class MethodResults(Protocol):
    """What a method run reads from an evaluation's results
    (:class:`rigmap.evaluation.metrics.MethodResult` is one): named here so that
    tracking, which evaluation logs through, does not import evaluation back."""

    def to_dict(self) -> dict[str, Any]: ...

    def per_frame_table(self) -> pd.DataFrame: ...


def experiment_name(rig: str, prefix: str = EXPERIMENT_PREFIX) -> str:
    return f"{prefix}-{safe_name(rig)}"


@dataclass(eq=False, repr=False)
class Tracker:
    """A checked connection to one tracking store; build with ``open`` or ``from_config``."""

    uri: str
    _: KW_ONLY
    root: Path
    experiment_prefix: str = EXPERIMENT_PREFIX
    register_models: bool = True
    system_metrics_interval_s: float | None = None
    client: MlflowClient = field(init=False)

    def __post_init__(self) -> None:
        self.client = MlflowClient(tracking_uri=self.uri, registry_uri=self.uri)

    @classmethod
    def open(
        cls,
        uri: str | None = None,
        *,
        root: str | os.PathLike | None = None,
        probe_timeout_s: float = DEFAULT_PROBE_TIMEOUT_S,
        request_timeout_s: int = DEFAULT_REQUEST_TIMEOUT_S,
        request_retries: int = DEFAULT_REQUEST_RETRIES,
        experiment_prefix: str = EXPERIMENT_PREFIX,
        register_models: bool = True,
        system_metrics_interval_s: float | None = None,
    ) -> Tracker:
        """Resolve the URI (argument > ``$MLFLOW_TRACKING_URI`` > local store) and check it."""
        project = project_folder(root)
        resolved = resolve_tracking_uri(uri, root=project)
        check_reachable(resolved, probe_timeout_s)
        if is_http_uri(resolved):
            bound_http_retries(request_timeout_s, request_retries)
        return cls(
            resolved,
            root=project,
            experiment_prefix=experiment_prefix,
            register_models=register_models,
            system_metrics_interval_s=system_metrics_interval_s,
        )

    @classmethod
    def from_config(cls, config: Mapping | None, *, root: str | os.PathLike | None = None):
        """From the Hydra ``tracking`` group (see conf/tracking/local.yaml for the fields)."""
        config = dict(config or {})
        known = {
            "uri",
            "probe_timeout_s",
            "request_timeout_s",
            "request_retries",
            "experiment_prefix",
            "register_models",
            "system_metrics_interval_s",
        }
        unknown = sorted(set(config) - known)
        if unknown:
            raise ValueError(
                f"tracking config: unknown fields {unknown}; expected {', '.join(sorted(known))}"
            )
        interval = config.get("system_metrics_interval_s")
        return cls.open(
            config.get("uri"),
            root=root,
            probe_timeout_s=float(config.get("probe_timeout_s", DEFAULT_PROBE_TIMEOUT_S)),
            request_timeout_s=config.get("request_timeout_s", DEFAULT_REQUEST_TIMEOUT_S),
            request_retries=config.get("request_retries", DEFAULT_REQUEST_RETRIES),
            experiment_prefix=str(config.get("experiment_prefix", EXPERIMENT_PREFIX)),
            register_models=bool(config.get("register_models", True)),
            system_metrics_interval_s=None if interval is None else float(interval),
        )

    def experiment_id(self, rig: str) -> str:
        """The id of experiment ``<prefix>-<rig>``, created on first use."""
        name = experiment_name(rig, self.experiment_prefix)
        found = self.client.get_experiment_by_name(name)
        if found is not None:
            if found.tags.get("mlflow.experimentKind") != EXPERIMENT_KIND:  # made before the tag
                self.client.set_experiment_tag(
                    found.experiment_id, "mlflow.experimentKind", EXPERIMENT_KIND
                )
            return found.experiment_id
        artifact_root = local_artifact_root(self.uri)
        location = (artifact_root / name).as_uri() if artifact_root is not None else None
        try:
            # MLflow 3 opens experiments of this kind on the runs list, not the GenAI overview
            tags = {"mlflow.experimentKind": EXPERIMENT_KIND}
            return self.client.create_experiment(name, artifact_location=location, tags=tags)
        except MlflowException:  # created by a concurrent process since we looked
            found = self.client.get_experiment_by_name(name)
            if found is None:
                raise
            return found.experiment_id

    def __repr__(self) -> str:
        return f"<Tracker {self.uri}>"


@dataclass
class ParentRun:
    """A sweep or pipeline run that method runs nest under. Use as a context manager."""

    tracker: Tracker
    rig: str
    run_id: str
    experiment_id: str
    children: list[str] = field(default_factory=list)

    _previous_sigterm: Any = field(default=None, repr=False)
    _monitor: Any = field(default=None, repr=False)

    def start_system_metrics(self, interval_s: float) -> None:
        """CPU, memory, disk and network as ``system/*`` metrics every ``interval_s`` (MLflow's
        monitor, psutil), until the run ends."""
        from mlflow.system_metrics.system_metrics_monitor import SystemMetricsMonitor

        self._monitor = SystemMetricsMonitor(
            self.run_id, sampling_interval=interval_s, tracking_uri=self.tracker.uri
        )
        self._monitor.start()

    def end(self, status: str = "FINISHED") -> None:
        if self._monitor is not None:
            self._monitor.finish()  # flushes the samples taken so far
            self._monitor = None
        self.tracker.client.set_terminated(self.run_id, status=status)

    def log_datasets(self, datasets: Sequence[DatasetInput]) -> None:
        """The files the sweep read, as MLflow datasets (see :mod:`rigmap.tracking.datasets`)."""
        if datasets:
            log_inputs(self.tracker.client, self.run_id, datasets)

    def log_table(self, table: pd.DataFrame, artifact_file: str) -> None:
        """A table artifact (MLflow's JSON table, shown as a grid in the run's artifacts)."""
        self.tracker.client.log_table(self.run_id, data=table, artifact_file=artifact_file)

    def __enter__(self) -> ParentRun:
        """While open, SIGTERM unwinds the stage (``RunKilled``) so the run ends KILLED."""
        if threading.current_thread() is threading.main_thread():
            self._previous_sigterm = signal.signal(signal.SIGTERM, _raise_run_killed)
        return self

    def __exit__(self, exc_type: object, *rest: object) -> None:
        if self._previous_sigterm is not None:
            signal.signal(signal.SIGTERM, self._previous_sigterm)
            self._previous_sigterm = None
        if exc_type is None:
            self.end("FINISHED")
        elif isinstance(exc_type, type) and issubclass(exc_type, RunKilled | KeyboardInterrupt):
            self.end("KILLED")
        else:
            self.end("FAILED")


class RunKilled(SystemExit):
    """SIGTERM arrived while a parent run was open; exits with 128 + the signal number."""


def _raise_run_killed(signum: int, frame: object) -> None:
    raise RunKilled(128 + signum)


def start_parent_run(
    tracker: Tracker,
    rig: str,
    *,
    name: str | None = None,
    config: Any = None,
    tags: Mapping[str, str] | None = None,
) -> ParentRun:
    """Open a parent run in the rig's experiment, with the sweep's config as params."""
    experiment = tracker.experiment_id(rig)
    all_tags = {"rig": rig, "kind": "sweep", **_git_tags(tracker.root), **(tags or {})}
    run = tracker.client.create_run(
        experiment, run_name=name or f"{rig}-{time.strftime('%Y%m%d-%H%M%S')}", tags=_tags(all_tags)
    )
    parent = ParentRun(tracker, rig, run.info.run_id, experiment)
    try:
        if tracker.system_metrics_interval_s:
            parent.start_system_metrics(tracker.system_metrics_interval_s)
        if config is not None:
            _log_params(tracker.client, parent.run_id, flatten_config(config))
    except BaseException:
        parent.end("FAILED")
        raise
    return parent


@dataclass(frozen=True)
class MappingToLog:
    """A fitted inverse mapping to attach to a method run as a pyfunc model (see pyfunc_model)."""

    mapping: Any
    regressor: str
    input_columns: Sequence[str]
    output_columns: Sequence[str]
    register: bool = True
    input_example: pd.DataFrame | None = None


@dataclass(frozen=True)
class MethodRun:
    run_id: str
    metrics: dict[str, float]
    model: LoggedMapping | None


def log_method_run(
    parent: ParentRun,
    *,
    rig: str,
    method: str,
    sampler: str,
    kernel: str | None,
    refine: str | None,
    config: Any,
    result: MethodResults | Mapping[str, Any],
    per_frame: pd.DataFrame | None = None,
    predicted_controls: pd.DataFrame | None = None,
    model: MappingToLog | None = None,
    tags: Mapping[str, str] | None = None,
    run_name: str | None = None,
    datasets: Sequence[DatasetInput] = (),
) -> MethodRun:
    """One method's child run: params, metrics, tags, datasets, artifacts and (optionally)
    its model.

    ``result`` is a ``MethodResult`` or its metrics JSON as a dict; with a dict,
    pass ``per_frame`` (the per-frame CSV as a DataFrame) to get the error plot.
    ``predicted_controls`` (clip, frame, one column per control) is stored as parquet;
    ``datasets`` are the files the run read (:func:`rigmap.tracking.datasets.dataset_input`).
    The run ends FINISHED, or FAILED if any step raised (and the error propagates).
    """
    if rig != parent.rig:
        raise ValueError(
            f"log_method_run: rig {rig!r} differs from the parent run's rig {parent.rig!r}; "
            "each rig has its own experiment and parent run"
        )
    client = parent.tracker.client
    summary = result.to_dict() if isinstance(result, MethodResults) else dict(result)
    if summary.get("rig", rig) != rig:
        raise ValueError(f"log_method_run: the metrics are for rig {summary['rig']!r}, not {rig!r}")
    if isinstance(result, MethodResults) and per_frame is None:
        per_frame = result.per_frame_table()
    metrics = method_metrics(summary)
    run_tags = {
        MLFLOW_PARENT_RUN_ID: parent.run_id,
        "rig": rig,
        "method": method,
        "sampler": sampler,
        "kernel": kernel or "none",
        "refine": refine or "none",
        **_git_tags(parent.tracker.root),
        **(tags or {}),
    }
    name = run_name or "-".join(part for part in (method, sampler, kernel) if part)
    run = client.create_run(parent.experiment_id, run_name=name, tags=_tags(run_tags))
    run_id = run.info.run_id
    parent.children.append(run_id)
    try:
        _log_params(client, run_id, flatten_config(config) if config is not None else {})
        _log_metrics(client, run_id, metrics, datasets)
        _log_run_artifacts(
            client, run_id, summary, config, per_frame, predicted_controls, title=f"{rig} · {name}"
        )
        logged = None
        if model is not None:
            logged = log_inverse_mapping(
                parent.tracker.uri,
                run_id,
                model.mapping,
                rig=rig,
                regressor=model.regressor,
                input_columns=model.input_columns,
                output_columns=model.output_columns,
                register=model.register and parent.tracker.register_models,
                input_example=model.input_example,
            )
            if logged.registered_name is not None and CHAMPION_METRIC in metrics:
                promote_if_better(
                    client, logged.registered_name, logged.version, metrics[CHAMPION_METRIC]
                )
    except BaseException:
        client.set_terminated(run_id, status=RunStatus.to_string(RunStatus.FAILED))
        raise
    client.set_terminated(run_id, status=RunStatus.to_string(RunStatus.FINISHED))
    return MethodRun(run_id, metrics, logged)


# --------------------------------------------------------------------------- helpers
def _log_run_artifacts(client, run_id, summary, config, per_frame, predicted_controls, *, title):
    """The run's files: metrics JSON, config, per-frame CSV and plot, predicted curves."""
    with tempfile.TemporaryDirectory(prefix="rigmap-run-") as scratch:
        folder = Path(scratch)
        write_text_atomic(folder / "metrics.json", _json(summary))
        if config is not None:
            artifacts.write_config_yaml(config, folder / "config.yaml")
        if per_frame is not None:
            write_text_atomic(folder / "per_frame.csv", per_frame.to_csv(index=False))
            artifacts.plot_per_frame_errors(
                per_frame,
                folder / "per_frame_error.png",
                title=title,
                length_unit=str(summary.get("length_unit", "cm")),
            )
        if predicted_controls is not None:
            artifacts.write_control_curves(
                predicted_controls, folder / "predicted_controls.parquet"
            )
        client.log_artifacts(run_id, str(folder))


def _log_params(client: MlflowClient, run_id: str, params: Mapping[str, str]) -> None:
    items = [Param(k, v) for k, v in params.items()]
    for start in range(0, len(items), _BATCH):
        client.log_batch(run_id, params=items[start : start + _BATCH])


#: how often a dataset insert that lost a race is tried again (ours: the winner has committed
#: by then, so the second try finds the dataset and only links it)
DATASET_RETRIES = 3


def log_inputs(client: MlflowClient, run_id: str, datasets: Sequence[DatasetInput]) -> None:
    """``client.log_inputs``, tried again when another stage inserted the same dataset first.

    MLflow's store looks a dataset up by (experiment, name, digest) and inserts it when
    missing; two stages running side by side that read the same file (the held-out and the
    training split's evaluations read one corpus) can both miss it, and the slower insert
    fails on the store's unique constraint. On the next try the dataset is there.
    """
    for attempt in range(DATASET_RETRIES + 1):
        try:
            client.log_inputs(run_id, datasets=list(datasets))
            return
        except MlflowException as error:
            if attempt == DATASET_RETRIES or not _lost_insert_race(error):
                raise
            time.sleep(0.2 * (attempt + 1))


def _lost_insert_race(error: BaseException) -> bool:
    """Whether ``error`` (or what caused it) is a unique-constraint violation."""
    while error is not None:
        text = str(error).lower()
        if "unique constraint" in text or type(error).__name__ == "IntegrityError":
            return True
        error = error.__cause__
    return False


def _log_metrics(
    client: MlflowClient,
    run_id: str,
    metrics: Mapping[str, float],
    datasets: Sequence[DatasetInput] = (),
) -> None:
    """The run's metrics, and the datasets they were measured on."""
    if datasets:
        log_inputs(client, run_id, datasets)
    now = int(time.time() * 1000)
    items = [Metric(k, v, now, 0) for k, v in metrics.items()]
    for start in range(0, len(items), 1000):  # MLflow's limit per batch
        client.log_batch(run_id, metrics=items[start : start + 1000])


def _tags(tags: Mapping[str, Any]) -> dict[str, str]:
    out = {str(k): truncate(str(v), MAX_TAG_VALUE_LENGTH) for k, v in tags.items()}
    if MLFLOW_RUN_NAME in out:
        raise ValueError(
            f"tags: set the run name with name=/run_name=, not the {MLFLOW_RUN_NAME} tag"
        )
    return out


def _git_tags(root: Path) -> dict[str, str]:
    """``git_commit`` (``unknown`` outside a checkout) and ``git_dirty`` (tracked files changed)."""

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(
                ["git", "--no-optional-locks", *args],
                cwd=root,
                capture_output=True,
                text=True,
                timeout=10,
                check=True,
            )
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip()

    commit = git("rev-parse", "HEAD")
    if commit is None:
        return {"git_commit": "unknown"}
    status = git("status", "--porcelain", "--untracked-files=no")
    return {"git_commit": commit, "git_dirty": "unknown" if status is None else str(bool(status))}


def _json(summary: Mapping[str, Any]) -> str:
    return json.dumps(summary, indent=2, allow_nan=False) + "\n"
