"""What every inverse-mapping regressor shares: the scikit-learn contract, files, fit hooks.

A :class:`Regressor` follows scikit-learn's ``BaseEstimator``: ``__init__`` only
stores its arguments, ``get_params`` reads them back from the signature (so
a Hydra config maps one to one onto a regressor, and ``sklearn.base.clone``
works), and fitted state lives in attributes ending in ``_``. It has one name,
``name``: the ``regressor`` config choice, the model id's first part and the
stem of its files (``<name>.json`` + payload, see :mod:`rigmap.regression.model_io`).

The fit stage (:mod:`rigmap.regression.fitting`) asks the model, through the
hooks below, what it needs instead of testing its class: extra ``fit``
arguments (``fit_options``), its kernel's label, and what to say about the fit
in its log and ``fit.json``. Whether a learned Jacobian is fitted beside it is
:func:`rigmap.regression.learned_jacobian.learned_jacobian_plan`'s answer.
Adding a regressor is one subclass plus one yaml file.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from sklearn.base import BaseEstimator

from rigmap.regression import model_io
from rigmap.regression.errors import ModelFileError
from rigmap.regression.fingerprint import ModelFingerprint

NO_KERNEL = "none"  # the kernel label of regressors that have none (the network)


class Regressor(BaseEstimator):
    """Base of the inverse mappings: pose features ``(N, D)`` -> used controls ``(N, C)``.

    Subclasses set ``name`` and implement ``fit`` (setting ``fingerprint_``),
    ``predict`` and, unless every fitted array is listed in ``saved_arrays``,
    ``_payload`` / ``_restore``.
    """

    #: the one name: config choice, model-id part, file stem and the ``kind`` in its JSON
    name: ClassVar[str] = ""
    #: names this model's files had before (still loaded, never written)
    legacy_names: ClassVar[tuple[str, ...]] = ()
    #: ``__init__`` arguments that hold a kernel (saved by ``to_dict``)
    kernel_params: ClassVar[tuple[str, ...]] = ()
    #: fitted ``<name>_`` arrays the default payload (an ``.npz``) holds
    saved_arrays: ClassVar[tuple[str, ...]] = ()
    payload_suffix: ClassVar[str] = ".npz"
    #: the parameters the short ``repr`` (which logs print) names; none: scikit-learn's repr
    repr_params: ClassVar[tuple[str, ...]] = ()

    fingerprint_: ModelFingerprint

    def __repr__(self, N_CHAR_MAX: int = 700) -> str:
        shown = self._repr_fields()
        if not shown:
            return super().__repr__(N_CHAR_MAX)
        fields = ", ".join(f"{name}={value}" for name, value in shown.items())
        return f"{type(self).__name__}({fields})"

    def _repr_fields(self) -> dict[str, Any]:
        """The short ``repr``'s values by name; a subclass may show derived ones instead."""
        return {name: getattr(self, name) for name in self.repr_params}

    # ------------------------------------------------------------------ the contract
    def fit(self, X: Any, Y: Any, **options: Any) -> Regressor:
        raise NotImplementedError

    def predict(self, X: Any) -> np.ndarray:
        raise NotImplementedError

    def is_fitted(self) -> bool:
        return hasattr(self, "fingerprint_")

    # ------------------------------------------------------------------ hooks for the fit stage
    def fit_options(self, *, rest_index: int) -> dict[str, Any]:
        """Extra ``fit`` keywords from the training rows (the GPR starts from the rest pose)."""
        return {}

    def rig_fit_options(self, *, rig: Any, placement: Any) -> dict[str, Any]:
        """Extra ``fit`` keywords for a model trained through the rig (``rig``, ``placement``)."""
        return {}

    @property
    def kernel_name(self) -> str:
        """The kernel part of the model id: the kernel's label, or ``none``."""
        kernel = getattr(self, "kernel", None)
        return kernel.label if kernel is not None else NO_KERNEL

    def describe_plan(self, rows: int) -> str:
        """One log line saying what ``fit`` is about to do."""
        return f"training {self!r} on {rows} rows"

    def describe_result(self) -> list[str]:
        """Log lines about a finished fit."""
        return []

    def fit_facts(self) -> dict[str, Any]:
        """Model-specific facts for ``fit.json`` (search, support, loss curve …)."""
        return {}

    # ------------------------------------------------------------------ files
    def save(self, folder: str | os.PathLike) -> Path:
        """Write ``<name>.json`` and the payload into ``folder`` (created if needed)."""
        if not self.is_fitted():
            raise RuntimeError(f"{type(self).__name__} is not fitted: nothing to save")
        meta = {
            "kind": self.name,
            "format_version": model_io.FORMAT_VERSION,
            "params": model_io.params_for_file(self.get_params()),
            "fingerprint": self.fingerprint_.to_dict(),
            **self._file_meta(),
        }
        payload = self._payload()
        return model_io.write_model_files(folder, self.name, payload, self.payload_suffix, meta)

    @classmethod
    def load(cls, folder: str | os.PathLike, rig: Any = None) -> Regressor:
        """Read a saved model; with ``rig`` (a Rig or its name), refuse a model of another rig."""
        meta, payload = model_io.read_model_files(
            folder, cls.name, cls.name, legacy=cls.legacy_names
        )
        source = f"{cls.name} model in {folder}"
        try:
            fingerprint = ModelFingerprint.from_dict(meta["fingerprint"])
            model = cls(**model_io.params_from_file(meta["params"], cls.kernel_params))
        except (KeyError, TypeError, ValueError) as error:
            raise ModelFileError(
                f"{source}: metadata is incomplete or invalid ({error!r})"
            ) from None
        fingerprint.check_rig(rig, source)
        model.fingerprint_ = fingerprint
        model._restore(meta, payload, source)
        return model

    def _file_meta(self) -> dict[str, Any]:
        """JSON fields beside params and fingerprint (fitted scalars, curves …)."""
        return {}

    def _payload(self) -> bytes:
        return model_io.arrays_to_bytes({n: getattr(self, f"{n}_") for n in self.saved_arrays})

    def _restore(self, meta: dict[str, Any], payload: bytes, source: str) -> None:
        """Set the fitted state from a file's metadata and payload (``fingerprint_`` is set)."""
        arrays = model_io.arrays_from_bytes(payload, source, self.saved_arrays)
        for name, values in arrays.items():
            setattr(self, f"{name}_", values)

    # ------------------------------------------------------------------ the known classes
    @classmethod
    def subclass_named(cls, name: str) -> type[Regressor]:
        """The imported regressor class whose ``name`` (or a legacy name) is ``name``."""
        for subclass in _all_subclasses(cls):
            if name == subclass.name or name in subclass.legacy_names:
                return subclass
        known = sorted(c.name for c in _all_subclasses(cls) if c.name)
        raise ModelFileError(f"no regressor is named {name!r}; known regressors: {known}")


def _all_subclasses(cls: type) -> list[type]:
    found = []
    for subclass in cls.__subclasses__():
        found += [subclass, *_all_subclasses(subclass)]
    return found


def regressor_classes() -> list[type[Regressor]]:
    """Every imported concrete regressor class (each has a ``name``)."""
    return [cls for cls in _all_subclasses(Regressor) if cls.name]
