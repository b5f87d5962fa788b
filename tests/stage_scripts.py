"""The pipeline scripts as modules, for tests that call a stage's ``run`` in-process."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

PIPELINES = Path(__file__).resolve().parents[1] / "pipelines"


def load_stage(name: str):
    """A pipelines/<name>.py module (they are scripts, not a package)."""
    sys.path.insert(0, str(PIPELINES))
    try:
        spec = importlib.util.spec_from_file_location(name, PIPELINES / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(PIPELINES))


def copy_stage_files(project: Path, source: Path = PIPELINES.parent) -> None:
    """The pipeline's stage files (``dvc.yaml`` and ``stages/*/dvc.yaml``) copied into
    ``project``, as a test's copy of the pipeline needs them."""
    import shutil

    from rigmap.store.pipeline_files import pipeline_files

    for path in pipeline_files(source):
        (project / path).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(source / path, project / path)
