"""Score a rig's methods on its test clips and write their metrics (the evaluate stage's work).

``evaluate`` takes plain objects — the rig, the methods by name (built from
``conf/method``), a :class:`rigmap.store.Layout` and :class:`EvaluationSettings` —
plans the set's jobs, checks every model folder exists, then runs each job and writes
``metrics/<rig>/<set>/<stem>.json`` and the per-frame
``metrics/<rig>/per_frame/<set>/<stem>.csv``. With an
:class:`~rigmap.evaluation.mlflow_runs.EvaluationLog` each job is also an MLflow child run, the
files read are datasets, and the set's table and a saved view of it end the record.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.clips import TestSet
from rigmap.evaluation.fitted_models import FittedModels
from rigmap.evaluation.jobs import EVALUATION_SETS, EvaluationJob, evaluation_jobs
from rigmap.evaluation.method import Method
from rigmap.evaluation.metrics import write_per_frame_csv
from rigmap.evaluation.runner import MethodEvaluation, run_method
from rigmap.store import Layout
from rigmap.store.layout import per_frame_file


@dataclass(frozen=True)
class EvaluationSettings:
    """What one evaluation runs and how (the ``evaluate`` config group, conf/evaluate/)."""

    set: str = "methods"
    test_split: str = "test"  # test | heldout | train (rigmap.evaluation.jobs.TEST_SPLITS)
    methods: tuple[str, ...] = ()
    samplers: tuple[str, ...] = ()
    kernels: tuple[str, ...] = ()
    clips: tuple[str, ...] | None = None  # test clips by name; None = all
    frames_per_clip: int | None = None  # score only the first N frames of each clip
    warmup_frames: int = 1  # untimed frames per clip before its timed pass
    log_to_mlflow: bool = True
    log_models: bool = True
    progress: bool = True

    def __post_init__(self) -> None:
        if self.set not in EVALUATION_SETS:
            raise EvaluationSetupError(
                f"evaluate.set: expected one of {EVALUATION_SETS}, got {self.set!r}"
            )
        for name in ("methods", "samplers", "kernels", "clips"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, tuple(str(v) for v in value))

    @classmethod
    def from_mapping(cls, config: Mapping[str, Any]) -> EvaluationSettings:
        """From the ``evaluate`` group as a plain mapping; unknown keys are an error."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(config) - known)
        if unknown:
            raise EvaluationSetupError(
                f"evaluate config: unknown keys {unknown}; expected {sorted(known)}"
            )
        return cls(**dict(config))


def evaluate(
    rig: Any,
    catalog: Mapping[str, Method],
    layout: Layout,
    settings: EvaluationSettings,
    *,
    nn_sampler: str,
    gpr_kernel: str,
    record: Mapping[str, Any] | None = None,
    log: Any = None,
) -> list[Path]:
    """Run the set ``settings.set`` names on ``rig``'s test clips; returns the files written.

    ``nn_sampler`` and ``gpr_kernel`` pick the models of the ``methods`` set;
    ``record`` is context written into every metrics JSON (experiment, budget);
    ``log`` an ``EvaluationLog`` (MLflow) or None.
    """
    jobs = evaluation_jobs(
        settings.set,
        rig.name,
        layout.metrics,
        methods=settings.methods,
        samplers=settings.samplers,
        kernels=settings.kernels,
        nn_sampler=nn_sampler,
        gpr_kernel=gpr_kernel,
        catalog=catalog,
        test_split=settings.test_split,
        replicate=layout.replicate,
    )
    models = FittedModels(layout, rig)
    models.check(jobs)  # every folder exists before minutes of work start
    test_set = TestSet.load(rig, layout, clips=settings.clips, split=settings.test_split)
    test_set = test_set.first_frames(settings.frames_per_clip)
    print(
        f"evaluate {rig.name} ({settings.set}): {len(jobs)} runs on {len(test_set.clips)} "
        f"{settings.test_split} clips, {test_set.frames} frames; warm-up "
        f"{settings.warmup_frames} frame(s) per clip (untimed)",
        flush=True,
    )
    if log is not None:
        log.log_datasets(layout, rig.name, jobs, settings.test_split)
    written = []
    for job in jobs:
        configured = catalog[job.method.name]
        evaluation = evaluate_job(job, configured, rig, test_set, models, settings, record)
        written += write_metrics(job, evaluation)
        if log is not None:
            log.log_job(job, configured, evaluation, models, rig, test_set)
    print_table(jobs, written)
    if log is not None:
        log.finish(jobs[0].metrics_path.parent.name)  # the set's metrics folder names its view
    return written


def evaluate_job(
    job: EvaluationJob,
    configured: Method,
    rig: Any,
    test_set: TestSet,
    models: FittedModels,
    settings: EvaluationSettings,
    record: Mapping[str, Any] | None = None,
) -> MethodEvaluation:
    """One job: its models loaded (once per evaluation), the method run, timed and scored."""
    method = configured  # the job's method, as the config built it
    print(f"{rig.name}: {method.name} (sampler {job.sampler}, kernel {job.kernel})", flush=True)
    learned = models.learned_jacobian(job) if method.needs_learned_jacobian else None
    regressor = models.regressor(job)
    if configured.tune is not None:  # tuned on each clip inside the clock (issue #15)
        from rigmap.regression.target_tuning import TunedOnTarget, TuningSettings

        regressor = TunedOnTarget(regressor, rig, TuningSettings(**configured.tune))
    return run_method(
        rig,
        method,
        test_set,
        regressor=regressor,
        learned_jacobian=learned,
        sampler=job.sampler,
        kernel=job.kernel,
        warmup_frames=int(settings.warmup_frames),
        extra={
            "model_folders": models.folders(job),
            "frames_per_clip": settings.frames_per_clip,
            **dict(record or {}),
        },
        progress=bool(settings.progress),
    )


def write_metrics(job: EvaluationJob, evaluation: MethodEvaluation) -> list[Path]:
    """The metrics JSON and its per-frame CSV (same stem, under ``per_frame/``)."""
    json_path = evaluation.result.write_json(job.metrics_path)
    csv_path = write_per_frame_csv(evaluation.result, per_frame_file(job.metrics_path))
    return [json_path, csv_path]


def print_table(jobs: Sequence[EvaluationJob], written: Sequence[Path]) -> None:
    """The averages of every job, as the terminal summary of the run."""
    print(
        f"{'run':34s} {'joint err':>11s} {'ground truth':>12s} {'time s':>9s} {'fps':>9s} "
        f"{'rig evals':>10s}"
    )
    for job in jobs:
        average = json.loads(job.metrics_path.read_text())["average"]
        print(
            f"{job.metrics_path.stem:34s} {average['joint_error']:11.4g} "
            f"{average['ground_truth_error']:12.4g} {average['total_time_s']:9.3g} "
            f"{average['fps']:9.4g} {average['rig_evaluations']:10d}"
        )
    print(f"joint error in cm² (mean over frames and 3J coordinates); {len(written)} files written")
