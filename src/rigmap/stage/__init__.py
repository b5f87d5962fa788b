"""The old name of :mod:`rigmap.app.stage` (``run_stage``), kept importable for stage scripts
written against it; dvc.yaml's stages also list this folder as a dependency. New code
imports :mod:`rigmap.app.stage` and :mod:`rigmap.app.inputs`."""

from rigmap.app.stage import run_stage

__all__ = ["run_stage"]
