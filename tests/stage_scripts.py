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
