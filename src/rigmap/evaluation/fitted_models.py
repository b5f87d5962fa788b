"""The fitted mappings an evaluation reads, found through the ``Layout`` and loaded once each.

A GPR serves several methods (the plain guess, both refinements, its learned Jacobian),
so each folder is read once per evaluation. ``check`` names every missing folder before
minutes of work start.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rigmap.evaluation.jobs import EvaluationJob
from rigmap.store import Layout

LEARNED_JACOBIAN_FOLDER = "learned_jacobian"  # inside the GPR's model folder (the fit stage's)


class FittedModels:
    """The rig's fitted mappings under ``layout.models/<rig>/<model id>/``."""

    def __init__(self, layout: Layout, rig: Any):
        self.layout = layout
        self.rig = rig
        self._loaded: dict[Path, object] = {}

    def regressor_folder(self, job: EvaluationJob) -> Path | None:
        model_id = job.model_id
        return None if model_id is None else self.layout.model(self.rig.name, model_id)

    def jacobian_folder(self, job: EvaluationJob) -> Path | None:
        model_id = job.jacobian_model_id
        if model_id is None:
            return None
        return self.layout.model(self.rig.name, model_id) / LEARNED_JACOBIAN_FOLDER

    def folders(self, job: EvaluationJob) -> dict[str, str | None]:
        """The job's model folders as written into its metrics JSON."""
        found = {
            "regressor": self.regressor_folder(job),
            "learned_jacobian": self.jacobian_folder(job),
        }
        return {k: None if v is None else v.as_posix() for k, v in found.items()}

    def check(self, jobs: Sequence[EvaluationJob]) -> None:
        """Raise ``FileNotFoundError`` naming every missing folder and the methods needing it."""
        needed: dict[Path, list[str]] = {}
        commands: dict[str, None] = {}  # ordered, no repeats
        for job in jobs:
            pairs = (
                (job.model_id, self.regressor_folder(job)),
                (job.jacobian_model_id, self.jacobian_folder(job)),
            )
            for model_id, folder in pairs:
                if folder is not None and not folder.is_dir():
                    needed.setdefault(folder, []).append(job.method.name)
                    commands[self._fit_command(model_id)] = None
        if needed:
            listing = "; ".join(f"{f} (for {', '.join(m)})" for f, m in needed.items())
            raise FileNotFoundError(
                f"model folders missing: {listing}. They are the fit stage's outputs "
                f"(dvc.yaml's fit_nn, fit_gpr, fit_mean, fit_nn_joint_space stages): run "
                + "; ".join(f"`{c}`" for c in commands)
            )

    def _fit_command(self, model_id) -> str:
        """The ``pipelines/fit.py`` command that writes ``model_id``'s folder."""
        command = (
            f"python pipelines/fit.py rig={self.rig.name} regressor={model_id.regressor} "
            f"sampler={model_id.sampler}"
        )
        if model_id.kernel != "none":
            command += f" kernel={model_id.kernel}"
        for field in ("data", "models"):  # where this evaluation looks, if not the default
            if getattr(self.layout, field) != Path(field):
                command += f" paths.{field}={getattr(self.layout, field)}"
        return command

    def regressor(self, job: EvaluationJob) -> Any:
        from rigmap.regression import load_regressor

        return self._load(self.regressor_folder(job), load_regressor)

    def learned_jacobian(self, job: EvaluationJob) -> Any:
        from rigmap.regression import load_learned_jacobian

        return self._load(self.jacobian_folder(job), load_learned_jacobian)

    def _load(self, folder: Path | None, loader) -> Any:
        if folder is None:
            return None
        if folder not in self._loaded:
            self._loaded[folder] = loader(folder, rig=self.rig)
        return self._loaded[folder]
