"""The rig's Jacobian learned by GPR, for refinement without rig evaluations (§4.3-4.4).

Finite-difference Jacobians need ``2 C`` rig evaluations per pose, far too many
for whole clips in a DCC. The paper computes them once at the subsampled poses
and regresses the flattened matrices with the same GPR as the controls, then
predicts and reshapes them at run time. The caller computes the training
Jacobians (``rigmap.refine.jacobian``) at the poses it chooses — typically the
inverse-mapping GPR's support points, ``gpr.support_points()`` with controls
``Y[gpr.support_indices_]``.

Predicting a derivative of the learned inverse instead would be less accurate:
kernel methods approximate values much better than derivatives (§7.1).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigmap.regression.base import Regressor
from rigmap.regression.errors import ModelFileError, RegressionInputError
from rigmap.regression.fingerprint import ModelFingerprint
from rigmap.regression.gpr import GaussianProcessRegressor
from rigmap.regression.kernels import Kernel, MultiquadricKernel
from rigmap.regression.model_io import arrays_from_bytes, arrays_to_bytes
from rigmap.regression.validation import as_float_array, check_finite

#: poses per kernel block when predicting (bounds the kernel matrix's memory; ours)
PREDICT_CHUNK = 4096

# the GPR settings a learned Jacobian shares with the GPR it is learned beside (§4.4)
GPR_SETTINGS = (
    "regularization",
    "search_length_scale",
    "n_length_scales",
    "cv_splits",
    "cv_max_outputs",
    "normalize",
    "seed",
)


@dataclass(eq=False, repr=False)
class LearnedJacobian(Regressor):
    """GPR from poses ``(N, D)`` to Jacobians ``(N, R, C)`` (R = 3 x joints, C = used controls).

    Every given pose is a support point (no subsampling: the poses are already
    the subsample). All Jacobian entries share one output scale, since they are
    the same kind of quantity; the length scale is searched as in §4.1.1 on a
    seeded random subset of ``cv_max_outputs`` varying entries, or taken from
    ``kernel`` when ``search_length_scale`` is false (e.g. the inverse-mapping
    GPR's ``kernel_``).
    """

    name = "learned_jacobian"
    kernel_params = ("kernel",)

    kernel: Kernel | None = None
    regularization: float = 1e-5
    search_length_scale: bool = True
    length_scale_range: Sequence[float] = (1e-4, 1e2)
    n_length_scales: int = 25
    cv_splits: int = 10
    cv_max_outputs: int | None = 256
    normalize: bool = True
    seed: int = 0

    def _regressor(self) -> GaussianProcessRegressor:
        """The GPR on the flattened Jacobians: every support pose, one shared output scale."""
        settings = {name: getattr(self, name) for name in GPR_SETTINGS}
        return GaussianProcessRegressor(
            kernel=self.kernel,
            n_points=None,
            length_scale_range=self.length_scale_range,
            output_scale="shared",
            **settings,
        )

    def fit(
        self,
        X: Any,
        jacobians: Any,
        *,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> LearnedJacobian:
        """Learn ``jacobians[i]`` (``(R, C)``, ``dx/dy``) at pose ``X[i]``.

        ``control_names`` names the ``C`` columns (the rig's used controls).
        """
        X = as_float_array(X, "LearnedJacobian.fit: poses X")
        J = as_float_array(jacobians, "LearnedJacobian.fit: jacobians")
        if X.ndim != 2:
            raise RegressionInputError(
                f"LearnedJacobian.fit: expected poses X of shape (N, D), got {X.shape}"
            )
        if J.ndim != 3 or len(J) != len(X):
            raise RegressionInputError(
                f"LearnedJacobian.fit: expected jacobians of shape ({len(X)}, R, C) — one "
                f"(rows, controls) matrix per pose — got {J.shape}"
            )
        check_finite(J.reshape(len(J), -1), "LearnedJacobian.fit: jacobians")
        self.jacobian_shape_ = (int(J.shape[1]), int(J.shape[2]))
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], J.shape[2], rig_name, control_names)
        self.__dict__.pop("_nonzero_entries", None)
        self.regressor_ = self._regressor().fit(X, J.reshape(len(J), -1), rig_name=rig_name)
        return self

    @property
    def length_scale_(self) -> float:
        return self.regressor_.length_scale_

    def predict(self, X: Any) -> np.ndarray:
        """Jacobians ``(M, R, C)`` at poses ``(M, D)`` (or ``(R, C)`` for one ``(D,)`` pose).

        Only the entries that are non-zero in some training Jacobian are predicted (a
        control moves only its own bone's descendants: 13 % of the quadruped's); the
        others are exactly 0 in the GPR's prediction anyway (zero mean, zero weights), so
        the result is the full GPR's up to the product's rounding, at 1/8 of its cost.
        """
        values, squeeze = self._predict_entries(X)
        flat = np.zeros((len(values), self.jacobian_shape_[0] * self.jacobian_shape_[1]))
        flat[:, self.nonzero_entries()] = values
        J = flat.reshape(len(values), *self.jacobian_shape_)
        return J[0] if squeeze else J

    def predict_entries(self, X: Any) -> np.ndarray:
        """``(M, E)``: the predicted values of :meth:`nonzero_entries` at poses ``(M, D)``
        (the compact form of :meth:`predict`, whose other entries are 0)."""
        values, _ = self._predict_entries(np.atleast_2d(np.asarray(X, dtype=np.float64)))
        return values

    def _predict_entries(self, X: Any) -> tuple[np.ndarray, bool]:
        if not hasattr(self, "regressor_"):
            raise RuntimeError("LearnedJacobian is not fitted: call fit(X, jacobians) first")
        X, squeeze = self.fingerprint_.check_inputs(X, "LearnedJacobian")
        gpr = self.regressor_
        weights, mean = self._compact_weights()
        values = np.empty((len(X), len(mean)))
        for start in range(0, len(X), PREDICT_CHUNK):
            Xn = (X[start : start + PREDICT_CHUNK] - gpr.x_mean_) / gpr.x_std_
            block = gpr.kernel_(Xn, gpr.support_inputs_) @ weights
            block += mean
            values[start : start + PREDICT_CHUNK] = block
        return values, squeeze

    def nonzero_entries(self) -> np.ndarray:
        """Flat indices of the entries any prediction can make non-zero (cached)."""
        cached = self.__dict__.get("_nonzero_entries")
        if cached is None:
            gpr = self.regressor_
            mean = np.broadcast_to(gpr.y_mean_, gpr.weights_.shape[1:])
            cached = np.flatnonzero((gpr.weights_ != 0).any(axis=0) | (mean != 0))
            scale = np.broadcast_to(gpr.y_std_, mean.shape)[cached]
            # the output scale folded into the weights: one product per prediction
            self.__dict__["_compact"] = (gpr.weights_[:, cached] * scale, mean[cached].copy())
            self.__dict__["_nonzero_entries"] = cached
        return cached

    def _compact_weights(self) -> tuple[np.ndarray, np.ndarray]:
        """The GPR's weights and mean on :meth:`nonzero_entries` only, output scale folded in."""
        self.nonzero_entries()  # builds them with the entries (cached together)
        return self.__dict__["_compact"]

    def pattern(self) -> np.ndarray:
        """``(R, C)`` bool: the entries a predicted Jacobian can make non-zero."""
        out = np.zeros(self.jacobian_shape_[0] * self.jacobian_shape_[1], dtype=bool)
        out[self.nonzero_entries()] = True
        return out.reshape(self.jacobian_shape_)

    def is_fitted(self) -> bool:
        return hasattr(self, "regressor_")

    def _file_meta(self) -> dict[str, Any]:
        gpr_meta, _ = self.regressor_.state()
        return {"jacobian_shape": list(self.jacobian_shape_), "gpr": gpr_meta}

    def _payload(self) -> bytes:
        return arrays_to_bytes(self.regressor_.state()[1])

    def _restore(self, meta: dict[str, Any], payload: bytes, source: str) -> None:
        try:
            shape = tuple(int(v) for v in meta["jacobian_shape"])
            gpr_meta = meta["gpr"]
        except (KeyError, TypeError, ValueError) as error:
            raise ModelFileError(
                f"{source}: metadata is incomplete or invalid ({error!r})"
            ) from None
        arrays = arrays_from_bytes(payload, source, GaussianProcessRegressor.saved_arrays)
        self.__dict__.pop("_nonzero_entries", None)
        self.regressor_ = GaussianProcessRegressor.from_state(gpr_meta, arrays, source)
        self.kernel = self.regressor_.kernel_  # as fitted (older files do not store it)
        if self.regressor_.fingerprint_.output_dim != shape[0] * shape[1]:
            raise ModelFileError(
                f"{source}: the GPR predicts {self.regressor_.fingerprint_.output_dim} numbers, "
                f"expected {shape[0]} x {shape[1]} from jacobian_shape"
            )
        self.jacobian_shape_ = (shape[0], shape[1])


def learned_jacobian_plan(regressor) -> tuple[np.ndarray, LearnedJacobian] | None:
    """§4.3-4.4: the rows at which to learn the rig's Jacobian beside a fitted regressor, and
    the unfitted model to learn it; ``None`` unless it is a multiquadric GPR (the paper gives
    the learned Jacobian to that model only).

    The Jacobian GPR takes the regressor's settings (regularisation, search range, splits,
    seed) and its fitted kernel, and learns at the regressor's support poses. It lives here,
    not on the GPR, because the learned Jacobian is itself a GPR: one direction of import.
    """
    if not isinstance(regressor, GaussianProcessRegressor):
        return None
    regressor._check_fitted()
    if not isinstance(regressor.kernel_, MultiquadricKernel):
        return None
    settings = {name: getattr(regressor, name) for name in GPR_SETTINGS}
    learned = LearnedJacobian(
        kernel=regressor.kernel_, length_scale_range=regressor.search_range, **settings
    )
    return np.asarray(regressor.support_indices_), learned
