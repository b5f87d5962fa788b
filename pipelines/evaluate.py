"""DVC stages ``evaluate``, ``evaluate_samplers``, ``evaluate_kernels``: methods on the test clips.

Reads the rig's test poses and animator controls (``<paths.data>/<rig>/poses/test.parquet``,
``corpus/test.parquet``; ``corpus/train.parquet`` for the ground-truth error's scale) and
the fitted mappings in ``<paths.models>/<rig>/<regressor>-<sampler>-<kernel>/``; writes
one metrics JSON and one per-frame CSV per run and logs a parent MLflow run with a child
run per method (``evaluate.log_to_mlflow``).

    python pipelines/evaluate.py rig=quadruped evaluate.set=methods   # metrics/<rig>/methods/
    python pipelines/evaluate.py rig=quadruped evaluate.set=samplers  # metrics/<rig>/samplers/
    python pipelines/evaluate.py rig=quadruped evaluate.set=kernels   # metrics/<rig>/kernels/

Each method run composes its own config, as if its groups had been chosen on the
command line (``regressor=gpr sampler=none refine=computed_jacobian ...``) on top of
this invocation's overrides; that config is what MLflow records for the run.
"""

from __future__ import annotations

from collections.abc import Sequence
from contextlib import nullcontext
from pathlib import Path

import hydra
import pandas as pd
from hydra.core.global_hydra import GlobalHydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from animate import rig_from_config
from rigmap.evaluation import (
    EvaluationJob,
    MethodEvaluation,
    RefineSettings,
    TestSet,
    evaluation_jobs,
    run_method,
    write_per_frame_csv,
)
from rigmap.sampling import sampler_name

CONFIG_DIR = Path(__file__).resolve().parents[1] / "conf"
SWAPPED_GROUPS = ("regressor", "sampler", "kernel", "refine")


def run(cfg: DictConfig, *, overrides: Sequence[str] = ()) -> list[Path]:
    """Run the set ``cfg.evaluate.set`` names; ``overrides`` are this invocation's (Hydra)."""
    settings = cfg.evaluate
    rig = rig_from_config(cfg.rig)
    jobs = evaluation_jobs(
        str(settings.set),
        rig.name,
        cfg.paths.metrics,
        methods=list(settings.methods),
        samplers=list(settings.samplers),
        kernels=list(settings.kernels),
        nn_sampler=sampler_name(cfg.sampler),
        gpr_kernel=kernel_name(cfg.kernel),
    )
    models = ModelFolders(Path(cfg.paths.models) / rig.name, rig)
    models.check(jobs)  # every folder exists before minutes of work start
    test_set = TestSet.load(
        rig, Path(cfg.paths.data) / rig.name, clips=_list_or_none(settings.clips)
    )
    test_set = test_set.first_frames(settings.frames_per_clip)
    configs = [method_config(job, overrides) for job in jobs]
    print(
        f"evaluate {rig.name} ({settings.set}): {len(jobs)} runs on {len(test_set.clips)} test "
        f"clips, {test_set.frames} frames; warm-up {settings.warmup_frames} frame(s) per clip "
        "(untimed)",
        flush=True,
    )

    parent = None
    if settings.log_to_mlflow:
        from rigmap.tracking import Tracker, start_parent_run

        tracker = Tracker.from_config(OmegaConf.to_container(cfg.tracking, resolve=True))
        parent = start_parent_run(
            tracker,
            rig.name,
            name=f"evaluate-{settings.set}",
            config=cfg,
            tags={"stage": "evaluate", "evaluation_set": str(settings.set)},
        )
        print(f"MLflow: {tracker.uri}, parent run {parent.run_id}", flush=True)
    written, logged_regressors = [], set()
    with parent if parent is not None else nullcontext():  # the parent ends FAILED on errors
        for job, job_cfg in zip(jobs, configs, strict=True):
            evaluation = evaluate_job(job, job_cfg, rig, test_set, models, settings)
            written += write_metrics(job, evaluation)
            if parent is not None:
                regressor = job.method.regressor
                log_model = bool(settings.log_models) and regressor not in (
                    None,
                    *logged_regressors,
                )
                log_run(parent, job, job_cfg, evaluation, models, rig, test_set, log_model)
                if log_model:
                    logged_regressors.add(regressor)
    print_table(jobs, written)
    return written


# --------------------------------------------------------------------------- configs
def kernel_name(kernel_cfg: DictConfig) -> str:
    """The kernel's name (``multiquadric`` ...) from the ``kernel`` group's ``_target_``."""
    return str(hydra.utils.instantiate(kernel_cfg).name)


def method_config(job: EvaluationJob, overrides: Sequence[str]) -> DictConfig:
    """The config of one method run: this invocation's overrides, then the method's groups.

    Group choices the set decides (regressor, sampler, kernel, refine) are replaced; value
    overrides inside those groups (``refine.damping=0.2``) are kept where the method's
    group has that key and dropped (with a note) where it has not.
    """
    method = job.method
    chosen = [f"sampler={job.sampler}", f"refine={method.refine}"]
    if method.regressor is not None:
        chosen.append(f"regressor={method.regressor}")
    if job.kernel is not None:
        chosen.append(f"kernel={job.kernel}")
    if method.jacobian is not None:
        chosen.append(f"refine.jacobian={method.jacobian}")
    kept, group_values = [], []
    for override in overrides:
        key = override.split("=", 1)[0].lstrip("+~")
        group = key.split(".", 1)[0]
        if key in SWAPPED_GROUPS:
            continue  # a group choice: the set decides it
        (group_values if group in SWAPPED_GROUPS else kept).append(override)
    base = _compose([*kept, *chosen])
    applicable = []
    for override in group_values:
        key = override.split("=", 1)[0].lstrip("+~")
        if OmegaConf.select(base, key, default=_MISSING) is not _MISSING:
            applicable.append(override)
        else:
            print(f"  note: {override!r} does not apply to {method.name} (no {key}); left out")
    return _compose([*kept, *applicable, *chosen]) if applicable else base


_MISSING = object()


def _compose(overrides: list[str]) -> DictConfig:
    if GlobalHydra.instance().is_initialized():
        return hydra.compose(config_name="config", overrides=overrides)
    with hydra.initialize_config_dir(config_dir=str(CONFIG_DIR), version_base="1.3"):
        return hydra.compose(config_name="config", overrides=overrides)


# --------------------------------------------------------------------------- models
class ModelFolders:
    """The rig's fitted mappings, loaded once each (a GPR serves several methods)."""

    def __init__(self, root: Path, rig):
        self.root = root
        self.rig = rig
        self._loaded: dict[Path, object] = {}

    def regressor_folder(self, job: EvaluationJob) -> Path | None:
        name = job.model_folder_name
        return None if name is None else self.root / name

    def jacobian_folder(self, job: EvaluationJob) -> Path | None:
        name = job.learned_jacobian_folder_name
        return None if name is None else self.root / name / "learned_jacobian"

    def check(self, jobs: list[EvaluationJob]) -> None:
        needed = {}
        for job in jobs:
            for folder in (self.regressor_folder(job), self.jacobian_folder(job)):
                if folder is not None and not folder.is_dir():
                    needed.setdefault(folder, []).append(job.method.name)
        if needed:
            listing = "; ".join(f"{f} (for {', '.join(m)})" for f, m in needed.items())
            raise FileNotFoundError(
                f"model folders missing: {listing}. They are the fit stage's outputs: run "
                f"`dvc repro fit` or `python pipelines/fit.py rig={self.rig.name} ...`"
            )

    def regressor(self, job: EvaluationJob):
        from rigmap.regression import load_regressor

        return self._load(self.regressor_folder(job), load_regressor)

    def learned_jacobian(self, job: EvaluationJob):
        from rigmap.regression import load_learned_jacobian

        return self._load(self.jacobian_folder(job), load_learned_jacobian)

    def _load(self, folder: Path | None, loader):
        if folder is None:
            return None
        if folder not in self._loaded:
            self._loaded[folder] = loader(folder, rig=self.rig)
        return self._loaded[folder]


# --------------------------------------------------------------------------- one run
def evaluate_job(
    job: EvaluationJob, job_cfg: DictConfig, rig, test_set: TestSet, models: ModelFolders, settings
) -> MethodEvaluation:
    method = job.method
    print(f"{rig.name}: {method.name} (sampler {job.sampler}, kernel {job.kernel})", flush=True)
    refine = None
    if method.refine != "none":
        refine = RefineSettings.from_config(
            OmegaConf.to_container(job_cfg.refine, resolve=True), method
        )
    folders = {
        "regressor": models.regressor_folder(job),
        "learned_jacobian": models.jacobian_folder(job),
    }
    return run_method(
        rig,
        method,
        test_set,
        regressor=models.regressor(job),
        learned_jacobian=models.learned_jacobian(job)
        if method.refine == "learned_jacobian"
        else None,
        refine=refine,
        sampler=job.sampler,
        kernel=job.kernel,
        warmup_frames=int(settings.warmup_frames),
        extra={
            "model_folders": {k: None if v is None else v.as_posix() for k, v in folders.items()},
            "frames_per_clip": settings.frames_per_clip,
            "experiment": HydraConfig.get().runtime.choices.get("experiment")
            if HydraConfig.initialized()
            else None,
            "budget": OmegaConf.to_container(job_cfg.budget, resolve=True),
        },
        progress=bool(settings.progress),
    )


def write_metrics(job: EvaluationJob, evaluation: MethodEvaluation) -> list[Path]:
    """The metrics JSON and, beside it, the per-frame CSV (same stem)."""
    json_path = evaluation.result.write_json(job.metrics_path)
    csv_path = write_per_frame_csv(evaluation.result, job.metrics_path.with_suffix(".csv"))
    return [json_path, csv_path]


def log_run(parent, job, job_cfg, evaluation, models, rig, test_set, log_model: bool):
    """The method's child run; with ``log_model``, its mapping as a registered pyfunc model."""
    from rigmap.regression.features import feature_names, inverse_features
    from rigmap.tracking import MappingToLog, log_method_run

    model = None
    if log_model:
        clip = test_set.clips[0]
        columns = feature_names(list(rig.joint_names))
        example = inverse_features(
            clip.positions[:2], clip.cog[:2], clip.cog_rotation[:2], n_joints=rig.n_joints,
            where="input example",
        )  # fmt: skip
        model = MappingToLog(
            models.regressor(job),
            job.method.regressor,
            input_columns=columns,
            output_columns=list(rig.used_controls),
            input_example=pd.DataFrame(example, columns=columns),
        )
    folder = models.regressor_folder(job)
    tags = {"stage": "evaluate", "jacobian": job.method.jacobian or "none"}
    if folder is not None:
        tags["model_folder"] = folder.as_posix()
    run = log_method_run(
        parent,
        rig=rig.name,
        method=job.method.name,
        sampler=job.sampler,
        kernel=job.kernel,
        refine=job.method.refine,
        config=job_cfg,
        result=evaluation.result,
        predicted_controls=evaluation.controls,
        model=model,
        tags=tags,
    )
    if run.model is not None and run.model.registered_name is not None:
        print(f"  registered {run.model.registered_name} version {run.model.version}")
    return run


def print_table(jobs: list[EvaluationJob], written: list[Path]) -> None:
    import json

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


def _list_or_none(value):
    return None if value is None else list(value)


@hydra.main(config_path="../conf", config_name="config", version_base="1.3")
def main(cfg: DictConfig) -> None:
    run(cfg, overrides=list(HydraConfig.get().overrides.task))


if __name__ == "__main__":
    main()
