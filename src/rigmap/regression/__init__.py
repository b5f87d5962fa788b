"""Inverse rig mappings learned by regression (paper §4-5): kernels, GPR, network, Jacobian.

Every model is scikit-learn style (hyper-parameters in ``__init__``, ``fit``,
``predict``) and saves to a folder as ``<kind>.json`` plus a data file; a
loaded model refuses inputs of the wrong width, NaNs, and rigs it was not
fitted for.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from rigmap.regression.gpr import (
    GaussianProcessRegressor,
    ModelFileError,
    ModelFingerprint,
    ModelMismatchError,
    RegressionInputError,
    greedy_subsample,
    length_scale_cv_errors,
    solve_regularized,
)
from rigmap.regression.kernels import (
    KERNELS,
    GaussianKernel,
    Kernel,
    LinearKernel,
    MultiquadricKernel,
    PolynomialKernel,
    kernel_from_dict,
    make_kernel,
)
from rigmap.regression.learned_jacobian import LearnedJacobian
from rigmap.regression.network import FeedForwardRegressor

REGRESSORS: dict[str, type] = {
    "gpr": GaussianProcessRegressor,
    "nn": FeedForwardRegressor,
}


def make_regressor(name: str, **params: Any):
    """An inverse-mapping regressor by its config name (``gpr`` or ``nn``).

    For ``gpr``, ``kernel`` may be a kernel object or a mapping with a ``name``
    field (as written by ``Kernel.to_dict``).
    """
    try:
        cls = REGRESSORS[name]
    except KeyError:
        raise ValueError(
            f"unknown regressor {name!r}; available regressors: {sorted(REGRESSORS)}"
        ) from None
    kernel = params.get("kernel")
    if kernel is not None and not isinstance(kernel, Kernel):
        params["kernel"] = kernel_from_dict(dict(kernel))
    return cls(**params)


def load_regressor(folder: str | os.PathLike, rig: Any = None):
    """The inverse mapping saved in ``folder`` (``gpr.json`` or ``network.json``).

    A folder written by a fit also holds ``placement.json``: the regressor then comes
    wrapped in its :class:`~rigmap.regression.mapping.InverseMapping` (pose rows in).
    """
    from rigmap.regression.mapping import InverseMapping, has_placement

    folder = Path(folder)
    if has_placement(folder):
        return InverseMapping.load(folder, rig=rig)
    found = [cls for cls in REGRESSORS.values() if (folder / f"{cls.file_stem}.json").is_file()]
    if len(found) != 1:
        expected = " or ".join(f"{cls.file_stem}.json" for cls in REGRESSORS.values())
        what = "both" if found else "neither"
        raise ModelFileError(f"{folder}: expected exactly one of {expected}, found {what}")
    return found[0].load(folder, rig=rig)


def load_learned_jacobian(folder: str | os.PathLike, rig: Any = None):
    """The learned Jacobian saved in ``folder``, wrapped with its placement if it has one."""
    from rigmap.regression.mapping import JacobianMapping, has_placement

    if has_placement(folder):
        return JacobianMapping.load(folder, rig=rig)
    return LearnedJacobian.load(folder, rig=rig)


__all__ = [
    "KERNELS",
    "REGRESSORS",
    "FeedForwardRegressor",
    "GaussianKernel",
    "GaussianProcessRegressor",
    "Kernel",
    "LearnedJacobian",
    "LinearKernel",
    "ModelFileError",
    "ModelFingerprint",
    "ModelMismatchError",
    "MultiquadricKernel",
    "PolynomialKernel",
    "RegressionInputError",
    "greedy_subsample",
    "kernel_from_dict",
    "length_scale_cv_errors",
    "load_learned_jacobian",
    "load_regressor",
    "make_kernel",
    "make_regressor",
    "solve_regularized",
]
