"""The whole mapping of a clip as an MLflow pyfunc model, so ``mlflow models serve`` answers it.

A request is one clip: a DataFrame with one row per frame, in frame order, and the
columns ``<joint>.x``, ``<joint>.y``, ``<joint>.z`` of every joint of the model's
:class:`~rigmap.map.partial.JointSubset` (world centimetres, the rig's axes: +Y up, the
character's left +X; i.e. what a :class:`~rigmap.map.JointMap` gives). Extra columns
(``frame``, other joints) are ignored. The answer has one row per frame and one column
per rig control, unused controls at their defaults: :func:`rigmap.map.clip.map_clip`'s
``controls`` — the subset mapping's guess, damped-least-squares refinement on the
targets, unwrapped and (optionally) smoothed curves, pinned feet, keys reduced within
the tolerance. Two request parameters override the saved settings: ``fps`` (for foot
contacts) and ``refine_iterations``.

Stored with the model (``data/map_model/``): the :class:`SubsetMapping` folder (its own
``save``), and ``map_model.json`` with the rig's name and used controls, the
:class:`~rigmap.map.clip.MapSettings`, the per-used-control training std and held values.
Models are data, not code (as in :mod:`rigmap.tracking.pyfunc_model`, whose checks this
reuses): the rig is built only from a registered rig name, regressors only from
rigmap's own classes, and every data path must stay inside the model folder. The model's
code is the installed rigmap: ``MLmodel`` names :mod:`rigmap.tracking.pyfunc_model` as
``loader_module`` (its one ``_load_pyfunc`` builds :class:`MapClipModel` for a
``data/map_model`` folder), no code file is copied into the folder, and nothing is pickled.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import mlflow
import numpy as np
import pandas as pd
from mlflow.exceptions import MlflowException
from mlflow.models import ModelSignature
from mlflow.protos.databricks_pb2 import INVALID_PARAMETER_VALUE
from mlflow.pyfunc import PythonModel
from mlflow.types import ColSpec, ParamSchema, ParamSpec, Schema

from rigmap.errors import RigmapError
from rigmap.map.clip import MapSettings, map_clip
from rigmap.map.joint_map import MappedTargets
from rigmap.map.partial import SubsetMapping
from rigmap.map.tracks import JointTracks, TracksError
from rigmap.store import write_folder_atomic, write_json_atomic
from rigmap.tracking.pyfunc_model import (
    LOADER_MODULE,
    MAP_DATA_FOLDER,
    UntrustedModelError,
    check_payload,
    inside_folder,
    joint_columns,
    pinned_requirements,
)

DATA_FOLDER = MAP_DATA_FOLDER  # the model's data folder, ``data/map_model``
MAPPING_ARTIFACT = "subset_mapping"
SPEC_ARTIFACT = "map_model"
SPEC_FORMAT = "rigmap.map_pyfunc/1"
REQUEST = "map model request"  # what error messages call the input
DEFAULT_FPS = 30.0  # ours: a request's frame rate unless it says (only foot contacts use it)


class MapModelError(RigmapError, ValueError):
    """A map model that cannot be saved as asked (std or held values of the wrong size, fps)."""


class MapModelInputError(RigmapError, MlflowException):
    """A request the map model cannot answer (missing joint columns, NaN, no frames).

    An ``MlflowException`` with ``INVALID_PARAMETER_VALUE``, so ``mlflow models serve``
    answers HTTP 400 with this message, not its generic "unexpected error" one.
    """

    def __init__(self, message: str):
        MlflowException.__init__(self, message, error_code=INVALID_PARAMETER_VALUE)


def input_frame(world: np.ndarray, joints: Sequence[str]) -> pd.DataFrame:
    """A request: ``(F, K, 3)`` world positions of ``joints`` as the model's input columns."""
    world = np.asarray(world, dtype=np.float64)
    return pd.DataFrame(world.reshape(len(world), -1), columns=joint_columns(joints))


class MapClipModel(PythonModel):
    """Pyfunc wrapper: a clip's joint targets in, every control per frame out (see module).

    ``model_root``: the saved model's folder; its data must stay inside it.
    """

    def __init__(self, model_root: str | os.PathLike):
        self._model_root = Path(model_root)

    def load_folder(self, data: Path) -> None:
        """The mapping and its spec from the model's data folder."""
        from rigmap.rigs import load

        paths = {
            SPEC_ARTIFACT: data / f"{SPEC_ARTIFACT}.json",
            MAPPING_ARTIFACT: data / MAPPING_ARTIFACT,
        }
        spec_file = inside_folder(paths[SPEC_ARTIFACT], self._model_root, "map model artifact")
        check_payload(paths[MAPPING_ARTIFACT], self._model_root)
        spec = read_spec(spec_file)
        self._rig = load(spec["rig"])
        check_spec_fits_rig(spec, self._rig, spec_file)
        self._mapping = SubsetMapping.load(paths[MAPPING_ARTIFACT], self._rig)
        self._settings = settings_from_dict(spec["settings"], spec_file)
        self._fps = float(spec["fps"])
        self._std = np.asarray(spec["control_std"], dtype=np.float64)
        self._hold = np.asarray(spec["hold_values"], dtype=np.float64)

    def predict(self, context: Any, model_input: pd.DataFrame, params: Any = None) -> Any:
        params = dict(params or {})
        fps = self._fps if params.get("fps") is None else float(params["fps"])
        joints = self._mapping.subset.joints
        try:
            settings = self._settings
            if params.get("refine_iterations") is not None:
                iterations = int(params["refine_iterations"])
                settings = dataclasses.replace(settings, refine_iterations=iterations)
            positions = request_positions(model_input, joints, fps)
            targets = MappedTargets(self._rig.name, joints, positions, fps, REQUEST, 1.0, (), ())
            result = map_clip(
                self._rig,
                targets,
                self._mapping,
                settings,
                control_std=self._std,
                hold_values=self._hold,
            )
        except MlflowException:
            raise
        except RigmapError as error:  # bad settings, frames without a heading ...: the request's
            raise MapModelInputError(f"map model: {error}") from None
        return pd.DataFrame(
            result.controls, columns=self._rig.control_names, index=model_input.index
        )


def request_positions(table: Any, joints: Sequence[str], fps: float) -> np.ndarray:
    """``(F, K, 3)`` from a request's ``<joint>.x/.y/.z`` columns; a clear error if not."""
    if not isinstance(table, pd.DataFrame):
        raise MapModelInputError(
            f"{REQUEST}: expected joint targets as a pandas DataFrame with one row per frame "
            f"and columns '<joint>.x/.y/.z', got {type(table).__name__}"
        )
    columns = joint_columns(joints)
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise MapModelInputError(
            f"{REQUEST}: lacks {len(missing)} of the {len(columns)} joint columns "
            f"it needs: {missing[:9]}{' ...' if len(missing) > 9 else ''} (joints "
            f"{list(joints)}, world cm, rig axes)"
        )
    try:
        values = table[columns].to_numpy(dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise MapModelInputError(
            f"{REQUEST}: joint columns are not all numbers ({error})"
        ) from None
    try:  # JointTracks names the joint, axis and row of a NaN or inf, or an empty clip
        tracks = JointTracks(
            tuple(joints), values.reshape(len(table), len(joints), 3), fps, "cm", REQUEST
        )
    except TracksError as error:
        raise MapModelInputError(str(error)) from None
    return tracks.positions


# --------------------------------------------------------------------------- the spec file
def settings_to_dict(settings: MapSettings) -> dict:
    return {
        k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(settings).items()
    }


def settings_from_dict(data: Any, where: str | os.PathLike) -> MapSettings:
    fields = {f.name for f in dataclasses.fields(MapSettings)}
    if not isinstance(data, dict) or set(data) - fields:
        raise UntrustedModelError(
            f"{where}: settings must be a mapping of MapSettings fields {sorted(fields)}, got "
            f"{sorted(data) if isinstance(data, dict) else type(data).__name__}"
        )
    return MapSettings(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})


def read_spec(path: Path) -> dict:
    """``map_model.json``, checked for its format and keys (never code, only data)."""
    try:
        spec = json.loads(path.read_text("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UntrustedModelError(f"{path}: not a readable map model file ({error})") from None
    keys = ("format", "rig", "used_controls", "settings", "fps", "control_std", "hold_values")
    missing = [k for k in keys if not isinstance(spec, dict) or k not in spec]
    if missing or spec["format"] != SPEC_FORMAT:
        raise UntrustedModelError(
            f"{path}: expected a {SPEC_FORMAT} file; missing {missing} or format "
            f"{spec.get('format') if isinstance(spec, dict) else None!r}"
        )
    if not isinstance(spec["rig"], str):
        raise UntrustedModelError(f"{path}: rig must be a registered rig name, got {spec['rig']!r}")
    return spec


def check_spec_fits_rig(spec: dict, rig, where: Path) -> None:
    """The rig built today has the used controls the model was saved with."""
    if list(spec["used_controls"]) != list(rig.used_controls):
        raise UntrustedModelError(
            f"{where}: the model was saved for rig {spec['rig']!r} with "
            f"{len(spec['used_controls'])} used controls; the rig {rig.name!r} built now has "
            f"{len(rig.used_controls)} that differ; re-export the model"
        )
    for key in ("control_std", "hold_values"):
        if np.shape(spec[key]) != (len(rig.used_controls),):
            raise UntrustedModelError(
                f"{where}: {key} has shape {np.shape(spec[key])}, expected "
                f"({len(rig.used_controls)},) (one per used control)"
            )


# --------------------------------------------------------------------------- saving
@dataclasses.dataclass(frozen=True, eq=False)
class MapModelParts:
    """What a map model is made of, one object for ``save_map_model`` and ``log_map_model``.

    ``control_std``/``hold_values``: per used control, as :func:`map_clip` takes them.
    ``input_example`` (a few frames, :func:`input_frame`) is stored as the model's serving
    example, and MLflow maps it once while saving: a check that the saved model works.
    """

    rig: Any
    mapping: SubsetMapping
    settings: MapSettings
    control_std: np.ndarray
    hold_values: np.ndarray
    fps: float = DEFAULT_FPS
    input_example: pd.DataFrame | None = None


def _write_artifacts(scratch: Path, parts: MapModelParts) -> str:
    """The model's data folder in ``scratch``: the mapping and ``map_model.json``."""
    rig, mapping, settings, fps = parts.rig, parts.mapping, parts.settings, parts.fps
    control_std, hold_values = parts.control_std, parts.hold_values
    scratch = scratch / DATA_FOLDER
    scratch.mkdir()
    mapping.subset.check_rig(rig)
    mapping.save(scratch / MAPPING_ARTIFACT)
    used = len(rig.used_controls)
    std, hold = (np.asarray(v, dtype=np.float64) for v in (control_std, hold_values))
    for name, values in (("control_std", std), ("hold_values", hold)):
        if values.shape != (used,) or not np.isfinite(values).all():
            raise MapModelError(
                f"{name}: expected {used} finite values (one per used control of rig "
                f"{rig.name!r}), got shape {values.shape}"
            )
    if not (np.isfinite(fps) and fps > 0):
        raise MapModelError(f"fps {fps!r} must be a positive number")
    spec = {
        "format": SPEC_FORMAT,
        "rig": rig.name,
        "subset": mapping.subset.name,
        "used_controls": list(rig.used_controls),
        "settings": settings_to_dict(settings),
        "fps": float(fps),
        "control_std": std.tolist(),
        "hold_values": hold.tolist(),
    }
    write_json_atomic(scratch / f"{SPEC_ARTIFACT}.json", spec)
    return str(scratch)


def _signature(parts: MapModelParts) -> ModelSignature:
    refine = ParamSpec("refine_iterations", "long", parts.settings.refine_iterations)
    params = ParamSchema([ParamSpec("fps", "double", float(parts.fps)), refine])
    return ModelSignature(
        inputs=Schema([ColSpec("double", c) for c in joint_columns(parts.mapping.subset.joints)]),
        outputs=Schema([ColSpec("double", c) for c in parts.rig.control_names]),
        params=params,
    )


@contextlib.contextmanager
def _model_arguments(parts: MapModelParts):
    """What ``save_model`` and ``log_model`` both take, its artifacts in a scratch folder
    that lasts as long as the ``with`` block."""
    with tempfile.TemporaryDirectory(prefix="rigmap-map-pyfunc-") as scratch:
        yield {
            "loader_module": LOADER_MODULE,
            "data_path": _write_artifacts(Path(scratch), parts),
            "signature": _signature(parts),
            "input_example": parts.input_example,
            "pip_requirements": pinned_requirements(SubsetMapping),
        }


def save_map_model(path: str | os.PathLike, parts: MapModelParts) -> Path:
    """Save the map model in folder ``path`` (replaced atomically; nothing half-written)."""
    with _model_arguments(parts) as arguments:
        return write_folder_atomic(
            path, lambda staging: mlflow.pyfunc.save_model(str(staging), **arguments)
        )


def log_map_model(
    parts: MapModelParts,
    *,
    name: str = "map_model",
    registered_model_name: str | None = None,
):
    """Log the map model into the active MLflow run (or a new one); its ``ModelInfo``.

    Registered as ``registered_model_name`` if given (e.g. ``rigmap-<rig>-map-<subset>``).
    """
    with _model_arguments(parts) as arguments:
        return mlflow.pyfunc.log_model(
            name=name, registered_model_name=registered_model_name, **arguments
        )


def export_map_model(
    out: str | os.PathLike,
    *,
    rig_name: str,
    mapping_folder: str | os.PathLike,
    layout=None,
    settings: MapSettings | None = None,
    fps: float = DEFAULT_FPS,
) -> Path:
    """The CLI's door: a saved SubsetMapping folder → a servable map model at ``out``.

    The training std and held values (per-control median) come from the rig's train corpus
    at ``layout`` (``data/<rig>/corpus/train.parquet``), as the mapping learnt from it.
    """
    from rigmap.animation.corpus_files import read_corpus_split
    from rigmap.error_measures import control_std
    from rigmap.rigs import load
    from rigmap.store import Layout

    rig = load(rig_name)
    mapping = SubsetMapping.load(mapping_folder, rig)
    Y = read_corpus_split(rig, layout or Layout(), "train").values()
    parts = MapModelParts(
        rig,
        mapping,
        settings or MapSettings(),
        control_std=control_std(Y),
        hold_values=np.median(Y, axis=0),
        fps=fps,
    )
    return save_map_model(out, parts)
