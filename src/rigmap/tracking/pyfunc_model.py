"""A fitted inverse mapping as an MLflow pyfunc model, registered as ``rigmap-<rig>-<regressor>``.

Any scikit-learn-style mapping works: ``predict(X (N, D)) -> (N, C)``,
``save(path)`` and a ``load(path)`` classmethod. The model is stored through
its own ``save`` (no pickling of the object), and rebuilt at load time by the
class that ``interface.json`` names, so ``mlflow.pyfunc.load_model`` in a fresh
process gives the same controls. The model's code is the installed rigmap: it is
logged with ``loader_module`` (this module's :func:`_load_pyfunc`) and its data under
``data/``, so no code file is copied into the model folder (no ``python_model``, no
``code_paths``) and nothing is cloudpickled; editing files in a model folder cannot
run code through rigmap's loader (:func:`load_pyfunc_model`, which checks ``MLmodel``
names this loader before MLflow reads it).

Models are data, not code: the name in ``interface.json`` is looked up in an
allow-list of rigmap's own mapping classes (:func:`allowed_mapping_classes`),
never imported, so a tampered model in a shared registry cannot make the loader
run what it names. A process that trusts another class says so in its own code
(:func:`allow_mapping_class`), not through the model file. Every payload path
(the mapping folder, the interface file, any file inside the folder, through
symlinks too) must stay inside the model's folder.

Input: joint positions as a DataFrame with columns ``<joint>.x``, ``<joint>.y``,
``<joint>.z`` (any extra columns are ignored, order does not matter); output: a
DataFrame of controls named by the rig's control names.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import os
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mlflow
import numpy as np
import pandas as pd
from mlflow.models import ModelSignature
from mlflow.pyfunc import PythonModel
from mlflow.types import ColSpec, Schema

from rigmap.errors import RigmapError
from rigmap.tracking.keys import safe_name

LOADER_MODULE = __name__  # what MLmodel names as the model's code: the installed rigmap
DATA_FOLDER = "inverse_mapping"  # the model's data folder, ``data/inverse_mapping``
MAPPING_ARTIFACT = "mapping"
INTERFACE_ARTIFACT = "interface"
INTERFACE_FORMAT = "rigmap.pyfunc_interface/1"


class MappingLoggingError(RigmapError, ValueError):
    """A mapping that cannot be logged as a pyfunc model (no save/load, not importable...)."""


class UntrustedModelError(RigmapError, ValueError):
    """A logged model that names a class outside the allow-list or a path outside its folder."""


_EXTRA_MAPPING_CLASSES: dict[str, type] = {}


def allowed_mapping_classes() -> dict[str, type]:
    """Name -> class of every mapping the pyfunc loader will build: rigmap's own, plus extras.

    Extras come only from :func:`allow_mapping_class` calls in the loading process.
    """
    from rigmap.regression import FeedForwardRegressor, GaussianProcessRegressor, LearnedJacobian
    from rigmap.regression.mapping import InverseMapping, JacobianMapping
    from rigmap.regression.mean import MeanRegressor

    own = (
        InverseMapping,
        JacobianMapping,
        GaussianProcessRegressor,
        FeedForwardRegressor,
        MeanRegressor,
    )
    classes = {cls.__name__: cls for cls in (*own, LearnedJacobian)}
    return {**classes, **_EXTRA_MAPPING_CLASSES}


def allow_mapping_class(cls: type, name: str | None = None) -> str:
    """Trust ``cls`` (e.g. a test's or a studio's own mapping) under ``name`` in this process."""
    name = name or cls.__name__
    known = allowed_mapping_classes().get(name)
    if known is not None and known is not cls:
        raise MappingLoggingError(f"mapping class name {name!r} is taken by {known!r}")
    _EXTRA_MAPPING_CLASSES[name] = cls
    return name


def mapping_class_name(cls: type) -> str:
    """The allow-list name of ``cls``: what ``interface.json`` stores."""
    for name, allowed in allowed_mapping_classes().items():
        if allowed is cls:
            return name
    raise MappingLoggingError(
        f"mapping class {cls.__module__}.{cls.__qualname__} is not one of rigmap's mapping "
        f"classes {sorted(allowed_mapping_classes())}; a loader builds only those (call "
        "rigmap.tracking.allow_mapping_class(cls) in the logging and the loading process)"
    )


def trusted_mapping_class(name: Any, where: str) -> type:
    """The allow-listed class called ``name``; a clear error naming ``where`` for anything else."""
    classes = allowed_mapping_classes()
    if not isinstance(name, str) or name not in classes:
        raise UntrustedModelError(
            f"{where}: mapping_class {name!r} is not one of rigmap's mapping classes "
            f"{sorted(classes)}; the model is refused (a model file never chooses code to run)"
        )
    return classes[name]


def inside_folder(path: str | os.PathLike, folder: str | os.PathLike, what: str) -> Path:
    """``path`` resolved (symlinks followed); refused if it leaves ``folder``."""
    resolved, root = Path(path).resolve(), Path(folder).resolve()
    if not resolved.is_relative_to(root):
        raise UntrustedModelError(
            f"{what}: path {str(path)!r} leads to {resolved}, outside the model folder {root}; "
            "the model is refused"
        )
    return resolved


def check_payload(folder: Path, root: Path) -> None:
    """Every file under the mapping folder stays inside the model folder (no escaping links)."""
    inside_folder(folder, root, "mapping artifact")
    if folder.is_dir():
        for item in folder.rglob("*"):
            inside_folder(item, root, f"mapping artifact file {item.relative_to(folder)}")


def joint_columns(joint_names: Sequence[str]) -> list[str]:
    """``["<joint>.x", "<joint>.y", "<joint>.z", ...]`` in joint order (the flattened ``x``)."""
    return [f"{joint}.{axis}" for joint in joint_names for axis in "xyz"]


def registered_model_name(rig: str, regressor: str) -> str:
    return f"rigmap-{safe_name(rig)}-{safe_name(regressor)}"


def class_path(cls: type) -> str:
    """``"module:QualName"`` of a class that a fresh process can import."""
    if cls.__module__ == "__main__" or "<locals>" in cls.__qualname__:
        raise MappingLoggingError(
            f"mapping class {cls.__qualname__!r} (module {cls.__module__!r}) cannot be imported "
            "by another process; define it at the top level of an importable module"
        )
    return f"{cls.__module__}:{cls.__qualname__}"


MAP_DATA_FOLDER = "map_model"  # a whole clip's map model (:mod:`rigmap.tracking.map_model`)

#: the data folders rigmap's one loader reads (:func:`_load_pyfunc`) and the wrapper each
#: holds, ``"module:Class"`` (named, not imported here, so this module needs no map code)
PYFUNC_WRAPPERS = {
    DATA_FOLDER: f"{__name__}:InverseMappingModel",
    MAP_DATA_FOLDER: "rigmap.tracking.map_model:MapClipModel",
}

#: rigmap's pyfunc loader (``loader_module``) and the data folders it reads
RIGMAP_LOADERS = {LOADER_MODULE: tuple(PYFUNC_WRAPPERS)}


def check_mlmodel(root: Path, loaders: Mapping[str, Sequence[str]] = RIGMAP_LOADERS) -> None:
    """``root/MLmodel`` loads its python_function flavour with one of ``loaders`` (module →
    its data folders) from ``data/<folder>``, and nothing else: no code, python_model or
    pickle."""
    import yaml

    path = root / "MLmodel"
    try:
        conf = yaml.safe_load(path.read_text("utf-8"))["flavors"]["python_function"]
        module = conf.get("loader_module")
        extra = [k for k in ("code", "python_model", "cloudpickle_version") if conf.get(k)]
    except (
        OSError,
        UnicodeDecodeError,
        yaml.YAMLError,
        LookupError,
        TypeError,
        AttributeError,
    ) as error:
        raise UntrustedModelError(f"{path}: not a readable pyfunc MLmodel ({error!r})") from None
    if module not in loaders or extra:
        raise UntrustedModelError(
            f"{path}: loader_module {module!r}{' with ' + str(extra) if extra else ''} is not "
            f"one of rigmap's loaders {sorted(loaders)}; the model is refused (its code must be "
            "the installed rigmap, never files in the model folder)"
        )
    allowed = [f"data/{folder}" for folder in loaders[module]]
    if conf.get("data") not in allowed:
        raise UntrustedModelError(
            f"{path}: data {conf.get('data')!r} is not {' or '.join(allowed)}; the model is refused"
        )


def checked_data_folder(data_path: str | os.PathLike, loader_module: str, name: str) -> Path:
    """The model folder of ``data_path`` (``<root>/data/<name>``), after :func:`check_mlmodel`
    and with every file under the data folder inside the model folder (links too)."""
    data = Path(data_path)
    if data.name != name or data.parent.name != "data":
        raise UntrustedModelError(
            f"{data}: a {loader_module} model keeps its data in data/{name}; the model is refused"
        )
    root = data.parent.parent
    check_mlmodel(root, {loader_module: (name,)})
    check_payload(data, root)
    return root


def load_pyfunc_model(model_uri: str):
    """rigmap's door to a logged or saved pyfunc model (a folder, ``runs:/``, ``models:/``):
    its ``MLmodel`` is checked to name one of rigmap's loaders (no code from the folder)
    before MLflow reads it; then ``mlflow.pyfunc.load_model``."""
    from mlflow.artifacts import download_artifacts

    local = Path(model_uri) if Path(model_uri).is_dir() else Path(download_artifacts(model_uri))
    check_mlmodel(local)
    return mlflow.pyfunc.load_model(str(local))


class LoadedPyfunc:
    """What :func:`_load_pyfunc` gives MLflow: ``predict(frame, params)`` of a wrapper,
    which ``unwrap_python_model()`` returns."""

    def __init__(self, python_model: Any):
        self.python_model = python_model

    def predict(self, model_input: Any, params: Any = None) -> Any:
        return self.python_model.predict(None, model_input, params)


def _load_pyfunc(data_path: str) -> LoadedPyfunc:
    """MLflow's ``loader_module`` entry for every rigmap pyfunc model: the wrapper of
    :data:`PYFUNC_WRAPPERS` its data folder names (``data/inverse_mapping`` or
    ``data/map_model``); any other folder is refused as not the inverse mapping's."""
    name = Path(data_path).name
    folder = name if name in PYFUNC_WRAPPERS else DATA_FOLDER
    root = checked_data_folder(data_path, LOADER_MODULE, folder)
    module, _, cls = PYFUNC_WRAPPERS[folder].partition(":")
    model = getattr(importlib.import_module(module), cls)(root)
    model.load_folder(Path(data_path))
    return LoadedPyfunc(model)


class InverseMappingModel(PythonModel):
    """Pyfunc wrapper: joint-position DataFrame in, control DataFrame out.

    ``model_root``: the logged model's folder; payload paths must stay in it.
    """

    def __init__(self, model_root: str | os.PathLike):
        self._model_root = Path(model_root)

    def load_folder(self, data: Path) -> None:
        """The mapping and interface from the model's data folder."""
        paths = {MAPPING_ARTIFACT: data / MAPPING_ARTIFACT}
        paths[INTERFACE_ARTIFACT] = data / "interface.json"
        root = self._model_root
        interface_file = inside_folder(paths[INTERFACE_ARTIFACT], root, "interface artifact")
        check_payload(paths[MAPPING_ARTIFACT], root)
        interface = _read_interface(interface_file)
        mapping_class = trusted_mapping_class(interface["mapping_class"], str(interface_file))
        self._mapping = mapping_class.load(paths[MAPPING_ARTIFACT])
        self._inputs = list(interface["input_columns"])
        self._outputs = list(interface["output_columns"])

    # MLflow reads this hint: a DataFrame means "no schema from hints" (the signature has it)
    def predict(self, context: Any, model_input: pd.DataFrame, params: Any = None) -> Any:
        if not isinstance(model_input, pd.DataFrame):
            raise TypeError(
                "inverse mapping: expected joint positions as a pandas DataFrame with columns "
                f"'<joint>.x/.y/.z', got {type(model_input).__name__}"
            )
        missing = [c for c in self._inputs if c not in model_input.columns]
        if missing:
            raise ValueError(
                f"inverse mapping: input lacks {len(missing)} of {len(self._inputs)} joint "
                f"columns, first {missing[:5]}"
            )
        X = model_input[self._inputs].to_numpy(dtype=np.float64)
        Y = np.asarray(self._mapping.predict(X), dtype=np.float64).reshape(len(X), -1)
        if Y.shape[1] != len(self._outputs):
            raise ValueError(
                f"inverse mapping: model gave {Y.shape[1]} controls per frame, "
                f"expected {len(self._outputs)}"
            )
        return pd.DataFrame(Y, columns=self._outputs, index=model_input.index)


def _read_interface(path: Path) -> dict:
    try:
        interface = json.loads(path.read_text("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise UntrustedModelError(f"{path}: not a readable interface file ({error})") from None
    missing = [
        key
        for key in ("format", "mapping_class", "input_columns", "output_columns")
        if not isinstance(interface, dict) or key not in interface
    ]
    if missing or interface["format"] != INTERFACE_FORMAT:
        raise UntrustedModelError(
            f"{path}: expected a {INTERFACE_FORMAT} interface file; missing {missing} or "
            f"format {interface.get('format') if isinstance(interface, dict) else None!r}"
        )
    return interface


@dataclass(frozen=True)
class LoggedMapping:
    """Where a logged mapping lives: its model URI, and its registry name and version."""

    model_uri: str
    registered_name: str | None
    version: str | None

    @property
    def registered_uri(self) -> str | None:
        if self.registered_name is None:
            return None
        return f"models:/{self.registered_name}/{self.version}"


def log_inverse_mapping(
    tracking_uri: str,
    run_id: str,
    mapping: Any,
    *,
    rig: str,
    regressor: str,
    input_columns: Sequence[str],
    output_columns: Sequence[str],
    register: bool = True,
    pip_requirements: Sequence[str] | None = None,
    input_example: pd.DataFrame | None = None,
    name: str = "inverse_mapping",
) -> LoggedMapping:
    """Log ``mapping`` into run ``run_id`` as a pyfunc model; register it unless told not to.

    Before logging, the mapping is saved and reloaded, and both copies must
    predict the same controls on a probe input of the declared width, so a
    model whose ``save``/``load`` loses state is refused here, not found later.
    No code is shipped with the model: a mapping class outside rigmap is trusted by
    :func:`allow_mapping_class` in the loading process. ``input_example`` (a few rows
    of joint positions) is stored with the model and MLflow runs the logged model
    on it once, as a check that the stored model loads and predicts.
    """
    input_columns, output_columns = (
        [str(c) for c in input_columns],
        [str(c) for c in output_columns],
    )
    mapping_class = _check_mapping(mapping)
    for what, columns in (("input", input_columns), ("output", output_columns)):
        if not columns or len(set(columns)) != len(columns):
            raise MappingLoggingError(f"{what}_columns: expected unique, non-empty column names")
    with tempfile.TemporaryDirectory(prefix="rigmap-pyfunc-") as scratch:
        data = Path(scratch) / DATA_FOLDER
        saved = data / MAPPING_ARTIFACT
        data.mkdir()
        mapping.save(str(saved))
        if not saved.exists():
            raise MappingLoggingError(
                f"{type(mapping).__name__}.save({str(saved)!r}) wrote nothing at that path"
            )
        _check_round_trip(
            mapping, mapping_class.load(str(saved)), len(input_columns), output_columns
        )
        interface = data / "interface.json"
        interface.write_text(
            json.dumps(
                {
                    "format": INTERFACE_FORMAT,
                    "mapping_class": mapping_class_name(mapping_class),
                    "rig": rig,
                    "regressor": regressor,
                    "input_columns": input_columns,
                    "output_columns": output_columns,
                },
                indent=1,
            ),
            encoding="utf-8",
        )
        signature = ModelSignature(
            inputs=Schema([ColSpec("double", c) for c in input_columns]),
            outputs=Schema([ColSpec("double", c) for c in output_columns]),
        )
        registered = registered_model_name(rig, regressor) if register else None
        mlflow.set_tracking_uri(tracking_uri)
        with mlflow.start_run(run_id=run_id, nested=mlflow.active_run() is not None):
            info = mlflow.pyfunc.log_model(
                name=name,
                loader_module=LOADER_MODULE,
                data_path=str(data),
                signature=signature,
                input_example=input_example,
                pip_requirements=list(pip_requirements or pinned_requirements(mapping_class)),
                registered_model_name=registered,
                await_registration_for=60,
            )
    version = info.registered_model_version
    return LoggedMapping(info.model_uri, registered, None if version is None else str(version))


def _check_mapping(mapping: Any) -> type:
    cls = type(mapping)
    missing = [m for m in ("predict", "save") if not callable(getattr(mapping, m, None))]
    if not callable(getattr(cls, "load", None)):
        missing.append("load (classmethod)")
    if missing:
        raise MappingLoggingError(
            f"{cls.__name__} cannot be logged as an inverse mapping: it lacks {missing}; "
            "expected predict(X), save(path) and a load(path) classmethod"
        )
    class_path(cls)  # a class another process can import at all
    mapping_class_name(cls)  # and one a loader will build
    return cls


def _check_round_trip(
    mapping: Any, reloaded: Any, input_width: int, output_columns: list[str]
) -> None:
    probe = np.linspace(-1.0, 1.0, 2 * input_width).reshape(2, input_width)
    before = np.asarray(mapping.predict(probe), dtype=np.float64).reshape(2, -1)
    after = np.asarray(reloaded.predict(probe), dtype=np.float64).reshape(2, -1)
    if before.shape[1] != len(output_columns):
        raise MappingLoggingError(
            f"{type(mapping).__name__}.predict gives {before.shape[1]} outputs per row, but "
            f"{len(output_columns)} output columns were declared"
        )
    if not np.allclose(before, after, rtol=1e-6, atol=1e-9):
        worst = float(np.abs(before - after).max())
        raise MappingLoggingError(
            f"{type(mapping).__name__}: save() then load() predicts differently "
            f"(largest difference {worst:.3g}); the saved model would not be the fitted one"
        )


def pinned_requirements(mapping_class: type) -> list[str]:
    """Pinned versions of what loading needs: mlflow, numpy, pandas, rigmap, the mapping's package.

    rigmap is always needed (the pyfunc wrapper lives in it); a package that is
    not an installed distribution (e.g. code shipped with ``code_paths``) adds nothing.
    """
    pins = [f"mlflow=={mlflow.__version__}", f"numpy=={np.__version__}"]
    pins.append(f"pandas=={pd.__version__}")
    distributions = importlib.metadata.packages_distributions()
    for top_level in dict.fromkeys(["rigmap", mapping_class.__module__.split(".")[0]]):
        for dist in distributions.get(top_level, []):
            pins.append(f"{dist}=={importlib.metadata.version(dist)}")
    return pins
