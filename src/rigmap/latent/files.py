"""Latent models on disk as arrays + JSON, so a model file is data and never code.

``fit/models.json`` + ``models.npz`` hold every label's scaling → PCA → GPLVM and its
labelled set; ``match/transitions.json`` + ``transitions.npz`` the matching points of
every model pair. Written and read through :mod:`rigmap.regression.model_io`: the JSON
names its payload and the payload's SHA-256 (the JSON is the commit), the payload must
stay inside the folder, and arrays load with ``allow_pickle=False``. The JSON has a
``kind`` and a ``format_version``; every array is checked against :data:`MODEL_SCHEMA`
or :data:`MATCH_SCHEMA` (kind and shape, sizes agreeing across arrays) before it is used,
so a planted pickle, a missing key or a wrong shape is one :class:`ModelFileError` naming
the file. The arrays are the fitted float64 values themselves (the Cholesky factor and
``K⁻¹Y`` too, not recomputed), so a loaded model gives the fitted model's numbers.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
import torch
from sklearn.decomposition import PCA

from rigmap.latent.control_scaling import ControlScaling
from rigmap.latent.gplvm import DTYPE, GPLVM, GPLVMSettings
from rigmap.latent.library import FittedModels, LabelledSet
from rigmap.latent.model import LatentModel
from rigmap.latent.transitions import MatchSet, TransitionTable
from rigmap.regression import model_io
from rigmap.regression.errors import ModelFileError

FIT_KIND, MATCH_KIND = "latent_fit", "latent_match"
FORMAT_VERSION = 1
#: one model's arrays (prefix ``model<i>.``): C used controls, d PCA components, N
#: training frames, q latent dimensions, H objective evaluations
MODEL_SCHEMA = {
    "scaling.weights": ("f", ("C",)),
    "scaling.mean": ("f", ("C",)),
    "scaling.lower": ("f", ("C",)),
    "scaling.upper": ("f", ("C",)),
    "pca.components_": ("f", ("d", "C")),
    "pca.mean_": ("f", ("C",)),
    "pca.explained_variance_": ("f", ("d",)),
    "pca.explained_variance_ratio_": ("f", ("d",)),
    "pca.singular_values_": ("f", ("d",)),
    "gplvm.X": ("f", ("N", "q")),
    "gplvm.Y": ("f", ("N", "d")),
    "gplvm.L": ("f", ("N", "N")),
    "gplvm.alpha": ("f", ("N", "d")),
    "gplvm.log_hyper": ("f", (3,)),
    "gplvm.times": ("f", ("N",)),
    "gplvm.segments": ("U", ("N",)),
    "gplvm.history": ("f", ("H",)),
}
#: one ordered pair's bridges (prefix ``pair<i>.``): K bridges in q latent dimensions
MATCH_SCHEMA = {
    "source_points": ("f", ("K", "q")),
    "target_points": ("f", ("K", "q")),
    "distance_cm": ("f", ("K",)),
    "control_distance": ("f", ("K",)),
}


# --------------------------------------------------------------------------- fitted models
def save_fitted(folder: Path, fitted: FittedModels) -> Path:
    """``models.npz`` then ``models.json`` (the commit) in ``folder``."""
    arrays, models = {}, []
    for i, (label, model) in enumerate(fitted.models.items()):
        entry = fitted.sets[label]
        arrays |= {f"model{i}.{k}": v for k, v in _model_arrays(model).items()}
        arrays |= {f"set{i}.take{k}": v for k, v in enumerate(entry.takes)}
        models.append({"label": label, "takes": list(entry.names), **_model_meta(model)})
    meta = {"kind": FIT_KIND, "format_version": FORMAT_VERSION, "models": models}
    meta["fit_seconds"] = dict(fitted.fit_seconds)
    return model_io.write_model_files(
        folder, "models", model_io.arrays_to_bytes(arrays), ".npz", meta
    )


def _model_arrays(model: LatentModel) -> dict[str, np.ndarray]:
    s, p, g = model.scaling, model.pca, model.gplvm
    return {
        **{f"scaling.{k}": getattr(s, k) for k in ("weights", "mean", "lower", "upper")},
        **{f"pca.{k}": getattr(p, k) for k in _PCA_ARRAYS},
        "gplvm.X": g.X,
        "gplvm.Y": g.Y.numpy(),
        "gplvm.L": g._L.numpy(),
        "gplvm.alpha": g._alpha.numpy(),
        "gplvm.log_hyper": g.log_hyper.numpy(),
        "gplvm.times": np.asarray(g.times, dtype=np.float64),
        "gplvm.segments": np.asarray(g.segments, dtype=str),
        "gplvm.history": np.asarray(g.history, dtype=np.float64),
    }


_PCA_ARRAYS = tuple(k[len("pca.") :] for k in MODEL_SCHEMA if k.startswith("pca."))
_GPLVM_SCALARS = ("data_variance", "kernel_variance", "lengthscale2", "white_variance")


def _model_meta(model: LatentModel) -> dict[str, Any]:
    p, g = model.pca, model.gplvm
    pca = {"n_components": p.n_components, "whiten": bool(p.whiten)}
    pca |= {"n_components_": int(p.n_components_), "n_samples_": int(p.n_samples_)}
    pca["noise_variance_"] = float(p.noise_variance_)
    gplvm = {"settings": dataclasses.asdict(g.settings), "iterations": int(g.iterations)}
    gplvm["converged"] = bool(g.converged)
    gplvm |= {k: float(getattr(g, k)) for k in _GPLVM_SCALARS}
    return {"controls": list(model.scaling.names), "pca": pca, "gplvm": gplvm}


def load_fitted(folder: Path) -> FittedModels:
    """The models :func:`save_fitted` wrote; a :class:`ModelFileError` naming the file if not."""
    meta, arrays, where = _read(folder, "models", FIT_KIND)
    models, sets = {}, {}
    try:
        for i, entry in enumerate(meta["models"]):
            label = str(entry["label"])
            own = _prefixed(arrays, f"model{i}.", MODEL_SCHEMA, where)
            sizes = {"C": len(entry["controls"]), "d": int(entry["pca"]["n_components_"])}
            model_io.check_arrays(own, MODEL_SCHEMA, f"{where} (model {label!r})", sizes)
            names = range(len(entry["takes"]))
            takes = [_take(arrays, f"set{i}.take{k}", sizes["C"], where) for k in names]
            sets[label] = LabelledSet(label, [str(n) for n in entry["takes"]], takes)
            models[label] = _model(arrays, f"model{i}.", entry)
        seconds = {str(k): float(v) for k, v in meta["fit_seconds"].items()}
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        if isinstance(error, ModelFileError):
            raise
        raise ModelFileError(f"{where}: metadata is incomplete or invalid ({error!r})") from None
    return FittedModels(models, sets, seconds)


def _model(arrays: dict, prefix: str, entry: dict) -> LatentModel:
    a = {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}
    scaling = ControlScaling(
        tuple(str(c) for c in entry["controls"]),
        *(a[f"scaling.{k}"] for k in ("weights", "mean", "lower", "upper")),
    )
    p = entry["pca"]
    pca = PCA(n_components=p["n_components"], svd_solver="full", whiten=bool(p["whiten"]))
    for k in _PCA_ARRAYS:
        setattr(pca, k, a[f"pca.{k}"])
    pca.n_components_, pca.n_samples_ = int(p["n_components_"]), int(p["n_samples_"])
    pca.noise_variance_, pca._fit_svd_solver = float(p["noise_variance_"]), "full"
    pca.n_features_in_ = len(scaling.names)
    return LatentModel(scaling, pca, _gplvm(a, entry["gplvm"]))


def _gplvm(a: dict, g: dict) -> GPLVM:
    gplvm = GPLVM(GPLVMSettings(**g["settings"]))
    gplvm.X = a["gplvm.X"]
    gplvm._X = torch.from_numpy(a["gplvm.X"].copy())
    gplvm.Y = torch.from_numpy(a["gplvm.Y"])
    gplvm._L, gplvm._alpha = torch.from_numpy(a["gplvm.L"]), torch.from_numpy(a["gplvm.alpha"])
    gplvm.log_hyper = torch.as_tensor(a["gplvm.log_hyper"], dtype=DTYPE)
    gplvm.segments = a["gplvm.segments"].astype(object)
    gplvm.times, gplvm.history = a["gplvm.times"], [float(v) for v in a["gplvm.history"]]
    gplvm.iterations, gplvm.converged = int(g["iterations"]), bool(g["converged"])
    for k in _GPLVM_SCALARS:
        setattr(gplvm, k, float(g[k]))
    return gplvm


def _take(arrays: dict, name: str, n_controls: int, where: str) -> np.ndarray:
    if name not in arrays:
        raise ModelFileError(f"{where}: array {name!r} is missing")
    model_io.check_arrays({name: arrays[name]}, {name: ("f", ("F", n_controls))}, where)
    return arrays[name]


# --------------------------------------------------------------------------- matching points
def save_table(folder: Path, table: TransitionTable) -> Path:
    """``transitions.npz`` then ``transitions.json`` (the commit) in ``folder``."""
    arrays, pairs = {}, []
    for i, ((a, b), m) in enumerate(table.matches.items()):
        arrays |= {f"pair{i}.{k}": getattr(m, k) for k in MATCH_SCHEMA}
        pairs.append({"source": a, "target": b, "candidates": int(m.candidates)})
    meta = {"kind": MATCH_KIND, "format_version": FORMAT_VERSION, "pairs": pairs}
    meta |= {"models": list(table.models), "threshold_cm": float(table.threshold_cm)}
    return model_io.write_model_files(
        folder, "transitions", model_io.arrays_to_bytes(arrays), ".npz", meta
    )


def load_table(folder: Path) -> TransitionTable:
    """The table :func:`save_table` wrote; a :class:`ModelFileError` naming the file if not."""
    meta, arrays, where = _read(folder, "transitions", MATCH_KIND)
    matches = {}
    try:
        models = tuple(str(m) for m in meta["models"])
        for i, pair in enumerate(meta["pairs"]):
            own = _prefixed(arrays, f"pair{i}.", MATCH_SCHEMA, where)
            model_io.check_arrays(own, MATCH_SCHEMA, where)
            a, b = str(pair["source"]), str(pair["target"])
            matches[(a, b)] = MatchSet(a, b, *own.values(), int(pair["candidates"]))
        threshold = float(meta["threshold_cm"])
    except (KeyError, TypeError, ValueError) as error:
        if isinstance(error, ModelFileError):
            raise
        raise ModelFileError(f"{where}: metadata is incomplete or invalid ({error!r})") from None
    missing = [(a, b) for a in models for b in models if a != b and (a, b) not in matches]
    if missing:
        raise ModelFileError(f"{where}: no matching points for the model pairs {missing}")
    return TransitionTable(matches, models, threshold)


# --------------------------------------------------------------------------- shared
def _read(folder: Path, stem: str, kind: str) -> tuple[dict, dict[str, np.ndarray], str]:
    """The checked JSON, every payload array by name, and what errors call the file."""
    meta, payload = model_io.read_model_files(folder, stem, kind)
    where = str(Path(folder) / f"{stem}.json")
    if meta.get("format_version") != FORMAT_VERSION:
        raise ModelFileError(
            f"{where}: format_version {meta.get('format_version')!r}, expected {FORMAT_VERSION}"
            " (re-run the stage that wrote it)"
        )
    arrays = model_io.arrays_from_bytes(payload, where, _npz_names(payload, where))
    return meta, {k: np.array(v) for k, v in arrays.items()}, where  # writable copies


def _npz_names(payload: bytes, where: str) -> list[str]:
    """The array names in an npz payload (an unreadable one is refused by name)."""
    import io
    import zipfile

    try:
        with zipfile.ZipFile(io.BytesIO(payload)) as archive:
            return [n[: -len(".npy")] for n in archive.namelist() if n.endswith(".npy")]
    except zipfile.BadZipFile as error:
        raise ModelFileError(f"{where}: not an npz of plain arrays ({error})") from None


def _prefixed(arrays: dict, prefix: str, schema: dict, where: str) -> dict[str, np.ndarray]:
    missing = [prefix + k for k in schema if prefix + k not in arrays]
    if missing:
        raise ModelFileError(f"{where}: arrays {missing[:5]} are missing")
    return {k: arrays[prefix + k] for k in schema}
