"""An evaluation's MLflow record: a parent run per invocation, a child run per method run.

All MLflow calls go through :mod:`rigmap.tracking` (the one door to MLflow); this
module decides what an evaluation logs: the stage's config on the parent, each
method's config, metrics, predicted curves and tags on its child, and each regressor
once per invocation as a registered pyfunc model (``log_models``). For a lead comparing
methods (issue #43): the corpus, test poses and samples read as datasets (their DVC md5 as
digest) on the parent and on each child that used them, the set's table (``table1.json``
for ``methods``; MLflow writes its numbers with 10 decimals, the metrics files hold them
whole) on the parent, and a saved view of the runs list, ``rigmap-<metrics set>``,
whose link the evaluation prints last.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

#: groups of the stage config that a child run states for itself
_RUN_GROUPS = ("method", "refine", "regressor", "sampler", "kernel")
#: the parent's table artifact and the saved view's title per evaluation set (the paper's
#: tables; the kernels of §7.1 have none)
TABLES = {
    "methods": ("table1.json", "Table 1"),
    "samplers": ("table2.json", "Table 2"),
    "kernels": ("kernels.json", "Kernels"),
}
#: the table's row of a run's averages (the report's name for it)
AVERAGE = "Average"


class EvaluationLog:
    """The parent run of one evaluation and the child runs logged under it."""

    def __init__(
        self,
        parent: Any,
        config: Mapping[str, Any],
        *,
        log_models: bool = True,
        set_name: str = "methods",
    ):
        self.parent = parent
        self.config = dict(config)
        self.log_models = bool(log_models)
        self.set_name = set_name
        self._logged_regressors: set[str] = set()
        self._inputs: dict[str, list] = {}  # context or "samples:<sampler>" -> dataset inputs
        self._rows: list[dict[str, Any]] = []

    @classmethod
    def start(
        cls,
        tracking: Mapping[str, Any],
        rig: str,
        set_name: str,
        config: Mapping[str, Any],
        *,
        log_models: bool = True,
    ) -> EvaluationLog:
        """Open the parent run ``evaluate-<set>`` in the rig's experiment (``tracking`` group)."""
        from rigmap.tracking import Tracker, start_parent_run

        tracker = Tracker.from_config(dict(tracking))
        parent = start_parent_run(
            tracker,
            rig,
            name=f"evaluate-{set_name}",
            config=dict(config),
            tags={"stage": "evaluate", "evaluation_set": set_name},
        )
        print(f"MLflow: {tracker.uri}, parent run {parent.run_id}", flush=True)
        return cls(parent, config, log_models=log_models, set_name=set_name)

    def __enter__(self) -> EvaluationLog:
        self.parent.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.parent.__exit__(*exc)  # the parent ends FAILED on errors

    def run_config(self, job, configured) -> dict[str, Any]:
        """The stage config with the groups this run decides replaced by its own."""
        config = {k: v for k, v in self.config.items() if k not in _RUN_GROUPS}
        config["method"] = {"name": job.method.name, **configured.config}
        config["refine"] = configured.config.get("refine", {"name": "none"})
        config["sampler"] = {"name": job.sampler}
        config["kernel"] = {"name": job.kernel}
        return config

    def log_datasets(self, layout, rig_name: str, jobs: Sequence[Any], split: str) -> None:
        """The training corpus, the scored split's corpus and poses, and the samples of each
        job's sampler as datasets of the parent; each child gets those it used (log_job).
        A samples file that is gone (a model fitted elsewhere) is named and left out."""
        from rigmap.tracking.datasets import DataFile, dataset_inputs

        def data_file(path: Path, context: str) -> DataFile:
            relative = Path(path).relative_to(layout.rig_data(rig_name)).with_suffix("")
            return DataFile(path, "-".join((rig_name, *relative.parts)), context)

        files = {
            "training": [data_file(layout.corpus(rig_name, "train"), "training")],
            "test": [
                data_file(layout.corpus(rig_name, split), "test"),
                data_file(layout.poses(rig_name, split), "test"),
            ],
        }
        for sampler in dict.fromkeys(job.sampler for job in jobs if job.sampler != "none"):
            path = layout.samples(rig_name, sampler)
            if path.is_file():
                files[f"samples:{sampler}"] = [data_file(path, "samples")]
            else:
                print(f"MLflow: {path} is missing: not logged as a dataset", flush=True)
        self._inputs = dataset_inputs(files)
        self.parent.log_datasets([i for group in self._inputs.values() for i in group])

    def _job_datasets(self, job) -> list:
        return [
            *self._inputs.get("training", ()),
            *self._inputs.get("test", ()),
            *self._inputs.get(f"samples:{job.sampler}", ()),
        ]

    def log_job(self, job, configured, evaluation, models, rig, test_set):
        """The job's child run; a regressor's first run also logs it as a registered model."""
        from rigmap.tracking import log_method_run

        regressor = job.method.regressor
        with_model = self.log_models and regressor is not None
        with_model = with_model and regressor not in self._logged_regressors
        folder = models.regressor_folder(job)
        tags = {"stage": "evaluate", "jacobian": job.method.jacobian or "none"}
        if folder is not None:
            tags["model_folder"] = folder.as_posix()
        run = log_method_run(
            self.parent,
            rig=rig.name,
            method=job.method.name,
            sampler=job.sampler,
            kernel=job.kernel,
            refine=job.method.refine,
            config=self.run_config(job, configured),
            result=evaluation.result,
            predicted_controls=evaluation.controls,
            model=mapping_to_log(models.regressor(job), regressor, rig, test_set)
            if with_model
            else None,
            tags=tags,
            datasets=self._job_datasets(job),
        )
        if with_model:
            self._logged_regressors.add(regressor)
        if run.model is not None and run.model.registered_name is not None:
            print(f"  registered {run.model.registered_name} version {run.model.version}")
        self._rows += table_rows(evaluation.result.to_dict(), job, run.run_id)
        return run

    def finish(self, metrics_set: str, ui_url: str | None = None) -> str:
        """The set's table on the parent and the saved view of its children; returns (and
        prints) the view's link. ``metrics_set`` is the metrics folder's name (``methods``,
        ``methods_heldout``, ``methods_seed1`` …): one view each, replaced by the next run."""
        from rigmap.tracking.views import (
            DEFAULT_UI_URL,
            runs_view_state,
            runs_view_url,
            save_runs_view,
            ui_base_url,
            view_id,
        )

        parent, tracker = self.parent, self.parent.tracker
        table_file, title = TABLES[self.set_name]
        parent.log_table(pd.DataFrame.from_records(self._rows), table_file)
        view = view_id(metrics_set)
        name = f"{title} ({metrics_set}), latest evaluation"
        save_runs_view(
            tracker.client, parent.experiment_id, view, name, runs_view_state(parent.run_id)
        )
        served = ui_url or ui_base_url(tracker.uri)
        url = runs_view_url(served or DEFAULT_UI_URL, parent.experiment_id, view)
        how = "" if served else f" (after `mlflow ui --backend-store-uri {tracker.uri}`)"
        print(f"MLflow: each method beside its errors and frames/s{how}: {url}", flush=True)
        return url


def table_rows(summary: Mapping[str, Any], job, run_id: str) -> list[dict[str, Any]]:
    """A run's rows of the set's table: one per test clip, then its average over all frames."""
    names = {
        "rig": summary["rig"],
        "method": job.method.name,
        "sampler": job.sampler,
        "kernel": job.kernel or "none",
        "refine": job.method.refine or "none",
    }
    motions = [*summary["clips"].items(), (AVERAGE, summary["average"])]
    return [{**names, "motion": m, **numbers, "run_id": run_id} for m, numbers in motions]


def mapping_to_log(model: Any, regressor: str, rig: Any, test_set: Any):
    """The fitted mapping as MLflow logs it, with named columns and a two-frame input example."""
    from rigmap.regression.features import feature_names, inverse_features
    from rigmap.tracking import MappingToLog

    clip = test_set.clips[0]
    columns = feature_names(list(rig.joint_names))
    example = inverse_features(
        clip.positions[:2],
        clip.cog[:2],
        clip.cog_rotation[:2],
        n_joints=rig.n_joints,
        where="input example",
    )
    return MappingToLog(
        model,
        regressor,
        input_columns=columns,
        output_columns=list(rig.used_controls),
        input_example=pd.DataFrame(example, columns=columns),
    )
