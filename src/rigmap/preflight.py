"""What a pipeline run will need, checked in its first seconds, before any stage runs.

A run of the quick pipeline takes half an hour; an error found by its 87th stage
(no Blender), its first evaluation (no tracking server) or its first write (a
read-only ``models/``) costs all of that. ``check_pipeline_needs`` asks up front:

- the Blender worker environment, when a stage file has a stage on a Blender rig;
- the MLflow tracking store, when the evaluation logs to it: one bounded request
  (``tracking.probe_timeout_s``, at most ``MAX_PROBE_TIMEOUT_S`` = 10 s) telling a
  closed port, a hung server and a failing one apart;
- every output folder (``paths.data/models/metrics/reports``): creatable and writable
  (a file is written and removed, so it holds for root and for read-only mounts too).

Every problem found is listed in one ``PreflightError``, one line each.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError
from rigmap.store.layout import ROOTS, Layout
from rigmap.store.pipeline_files import stage_families

OUTPUT_FOLDERS = ROOTS


class PreflightError(RigmapError, ValueError):
    """Something the pipeline needs is missing; found before any stage ran."""


def check_pipeline_needs(
    project: str | os.PathLike, params: Mapping[str, Any], environ: Mapping[str, str]
) -> list[str]:
    """The checks run (one line each); ``PreflightError`` listing every problem found."""
    project = Path(project)
    checks, problems = [], []
    for name, check in (
        ("Blender worker environment", lambda: _blender(project, params)),
        ("tracking store", lambda: _tracking(project, params, environ)),
        ("output folders", lambda: _output_folders(project, params)),
    ):
        found = check()
        if found is None:
            continue
        problems.extend(found)
        checks.append(f"{name}: {'ok' if not found else 'FAILED'}")
    if problems:
        raise PreflightError(
            f"preflight: {len(problems)} problem(s) found before any stage ran:\n  - "
            + "\n  - ".join(problems)
        )
    return checks


def blender_rigs(project: Path, params: Mapping[str, Any] | None = None) -> list[str]:
    """Rigs of the stage matrices (``dvc.yaml``, ``stages/*/dvc.yaml``) that are Blender rigs.

    A matrix may name its list in the params (``rig: ${pipeline.blender_rigs}``, as DVC
    interpolates it); that list is read from ``params``.
    """
    rigs: list[str] = []
    for family in stage_families(project).values():
        matrix = family.body.get("matrix")
        listed = (matrix or {}).get("rig", []) if isinstance(matrix, Mapping) else []
        for rig in _interpolated(listed, params or {}):
            config = Layout.project_conf(project) / "rig" / f"{rig}.yaml"
            if rig not in rigs and config.is_file() and "blender" in config.read_text("utf-8"):
                rigs.append(str(rig))
    return rigs


def _interpolated(value: Any, params: Mapping[str, Any]) -> list:
    """A matrix list, or the params list a ``${dotted.key}`` string names (else empty)."""
    if isinstance(value, str) and value.startswith("${") and value.endswith("}"):
        for key in value[2:-1].split("."):
            params = params.get(key) if isinstance(params, Mapping) else None
        value = params
    return list(value) if isinstance(value, list | tuple) else []


def _blender(project: Path, params: Mapping[str, Any]) -> list[str] | None:
    rigs = blender_rigs(project, params)
    if not rigs:
        return None
    from rigmap.rigs.blender import BlenderNotFoundError, find_blender

    try:
        find_blender()
    except BlenderNotFoundError as error:
        return [f"stages on the Blender rig(s) {rigs} need Blender: {error}"]
    return []


def _tracking(project: Path, params: Mapping[str, Any], environ: Mapping[str, str]):
    evaluate = params.get("evaluate") or {}
    if not evaluate.get("log_to_mlflow", False):
        return None
    from rigmap.tracking.store import (
        DEFAULT_PROBE_TIMEOUT_S,
        TrackingUnavailableError,
        check_reachable,
        resolve_tracking_uri,
    )

    tracking = params.get("tracking") or {}
    uri = resolve_tracking_uri(tracking.get("uri"), root=project, environ=environ)
    try:
        check_reachable(uri, float(tracking.get("probe_timeout_s") or DEFAULT_PROBE_TIMEOUT_S))
    except TrackingUnavailableError as error:
        return [f"evaluate.log_to_mlflow is true but {error}"]
    return []


def _output_folders(project: Path, params: Mapping[str, Any]) -> list[str]:
    paths = params.get("paths") or {}
    problems = []
    for key in OUTPUT_FOLDERS:
        folder = project / str(paths.get(key, key))
        problem = _writable(folder)
        if problem:
            problems.append(f"paths.{key} = {folder}: {problem}")
    return problems


def _writable(folder: Path) -> str | None:
    """Why nothing can be written in ``folder`` (created if missing), or ``None``."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".rigmap-preflight-"):
            pass
    except OSError as error:
        what = "is a file, not a folder" if folder.is_file() else "cannot be written"
        return f"{what} ({error.strerror or error}); the stages write their outputs there"
    return None
