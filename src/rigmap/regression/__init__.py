"""Inverse rig mappings learned by regression (paper §4-5): kernels, GPR, network, Jacobian.

Every model is a :class:`~rigmap.regression.base.Regressor` (scikit-learn's
estimator contract: hyper-parameters in ``__init__``, ``fit``, ``predict``),
built from its config with ``hydra.utils.instantiate``, and saves to a folder as
``<name>.json`` plus a data file (:mod:`rigmap.regression.model_io`); a loaded
model refuses inputs of the wrong width, NaNs, and rigs it was not fitted for.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from rigmap.gp.solve import solve_regularized
from rigmap.regression.base import Regressor, regressor_classes
from rigmap.regression.errors import ModelFileError, ModelMismatchError, RegressionInputError
from rigmap.regression.fingerprint import ModelFingerprint
from rigmap.regression.gpr import GaussianProcessRegressor
from rigmap.regression.joint_space_network import JointSpaceNetworkRegressor
from rigmap.regression.kernels import (
    GaussianKernel,
    Kernel,
    LinearKernel,
    MultiquadricKernel,
    PolynomialKernel,
    ScaleKernel,
    SumKernel,
    kernel_from_dict,
)
from rigmap.regression.learned_jacobian import LearnedJacobian
from rigmap.regression.length_scale_search import length_scale_cv_errors
from rigmap.regression.mean import MeanRegressor
from rigmap.regression.network import FeedForwardRegressor
from rigmap.regression.subsampling import greedy_subsample


def load_regressor(folder: str | os.PathLike, rig: Any = None):
    """The inverse mapping saved in ``folder`` (``<name>.json`` of one known regressor).

    A folder written by a fit also holds ``placement.json``: the regressor then comes
    wrapped in its :class:`~rigmap.regression.mapping.InverseMapping` (pose rows in).
    """
    from rigmap.regression.mapping import InverseMapping, has_placement
    from rigmap.regression.model_io import has_model_file

    folder = Path(folder)
    if has_placement(folder):
        return InverseMapping.load(folder, rig=rig)
    if (folder / "fit.json").is_file():  # a fit always writes the placement beside the model
        raise ModelFileError(
            f"{folder}: placement.json is missing; the fit stage writes it beside every model, "
            "and without it the model would read world-placed poses as placement-free ones "
            "(re-run the fit stage for this model)"
        )
    classes = [cls for cls in regressor_classes() if cls is not LearnedJacobian]
    found = [cls for cls in classes if has_model_file(folder, (cls.name, *cls.legacy_names))]
    if len(found) != 1:
        expected = " or ".join(f"{cls.name}.json" for cls in classes)
        what = "several" if found else "none"
        raise ModelFileError(f"{folder}: expected exactly one of {expected}, found {what}")
    return found[0].load(folder, rig=rig)


def load_learned_jacobian(folder: str | os.PathLike, rig: Any = None):
    """The learned Jacobian saved in ``folder``, wrapped with its placement if it has one."""
    from rigmap.regression.mapping import JacobianMapping, has_placement

    if has_placement(folder):
        return JacobianMapping.load(folder, rig=rig)
    return LearnedJacobian.load(folder, rig=rig)


__all__ = [
    "FeedForwardRegressor",
    "GaussianKernel",
    "GaussianProcessRegressor",
    "JointSpaceNetworkRegressor",
    "Kernel",
    "LearnedJacobian",
    "LinearKernel",
    "MeanRegressor",
    "ModelFileError",
    "ModelFingerprint",
    "ModelMismatchError",
    "MultiquadricKernel",
    "PolynomialKernel",
    "RegressionInputError",
    "Regressor",
    "ScaleKernel",
    "SumKernel",
    "greedy_subsample",
    "kernel_from_dict",
    "length_scale_cv_errors",
    "load_learned_jacobian",
    "load_regressor",
    "regressor_classes",
    "solve_regularized",
]
