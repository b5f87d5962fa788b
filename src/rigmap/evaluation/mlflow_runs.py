"""An evaluation's MLflow record: a parent run per invocation, a child run per method run.

All MLflow calls go through :mod:`rigmap.tracking` (the one door to MLflow); this
module decides what an evaluation logs: the stage's config on the parent, each
method's config, metrics, predicted curves and tags on its child, and each regressor
once per invocation as a registered pyfunc model (``log_models``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import pandas as pd

#: groups of the stage config that a child run states for itself
_RUN_GROUPS = ("method", "refine", "regressor", "sampler", "kernel")


class EvaluationLog:
    """The parent run of one evaluation and the child runs logged under it."""

    def __init__(self, parent: Any, config: Mapping[str, Any], *, log_models: bool = True):
        self.parent = parent
        self.config = dict(config)
        self.log_models = bool(log_models)
        self._logged_regressors: set[str] = set()

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
        return cls(parent, config, log_models=log_models)

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
        )
        if with_model:
            self._logged_regressors.add(regressor)
        if run.model is not None and run.model.registered_name is not None:
            print(f"  registered {run.model.registered_name} version {run.model.version}")
        return run


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
