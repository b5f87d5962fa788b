"""Gaussian process regression for the inverse rig mapping (paper §4.1-4.2).

The prediction is the regularised GP mean of Eq. 6,
``y* = K* (K + theta1 I)^-1 Y``, for every output at once. Fitting has two
parts, both from the paper, each in its own module:

- **length-scale line search** (§4.1.1, :mod:`~rigmap.regression.length_scale_search`):
  candidate values spaced regularly in log scale over a range; for each, 10
  times train on a random half of the data and validate on the other half;
  keep the value with the lowest mean error;
- **greedy subsampling** (§4.2, :mod:`~rigmap.regression.subsampling`): start
  from the rest pose, add a few farthest points (Eq. 7), then repeatedly the
  point the current GP predicts worst (Eq. 10) until ``n_points`` are chosen.

The solve is :func:`~rigmap.gp.solve.solve_regularized` (LU,
never Cholesky: the multiquadric Gram matrix is indefinite).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from threadpoolctl import threadpool_limits

from rigmap.gp.kernels import Kernel, MultiquadricKernel, kernel_from_dict
from rigmap.gp.solve import solve_regularized
from rigmap.regression.base import Regressor
from rigmap.regression.errors import ModelFileError, RegressionInputError
from rigmap.regression.fingerprint import ModelFingerprint
from rigmap.regression.length_scale_search import length_scale_cv_errors
from rigmap.regression.model_io import arrays_from_bytes, params_for_file, params_from_file
from rigmap.regression.normalisation import column_scale
from rigmap.regression.subsampling import greedy_subsample
from rigmap.regression.validation import check_training_data

# Below this the fitted model warns that its predictions may amplify round-off.
_WARN_RCOND = 1e-12
_PREDICT_CHUNK = 8192

OutputScale = Literal["per_output", "shared"]


@dataclass(eq=False, repr=False)
class GaussianProcessRegressor(Regressor):
    """GPR inverse mapping: joint positions ``(N, D)`` -> controls ``(N, C)`` (§4.1-4.2).

    Parameters (the paper's values are the defaults):

    - ``kernel``: a ``rigmap.regression.kernels`` object (multiquadric, Eq. 1).
    - ``regularization``: ``theta1`` of Eq. 6, added to the Gram diagonal.
    - ``n_points``: support points kept by greedy subsampling; ``None`` keeps
      every training row (no subsampling).
    - ``search_length_scale``: run the §4.1.1 line search; if false the
      kernel's own ``length_scale`` is used.
    - ``length_scale_range``, ``n_length_scales``: candidates spaced regularly in
      log scale over the range (the paper's range is 1e-4..1e2 and says
      "regularly"; 25 values = 4 per decade is our choice). ``None``: the
      kernel's own ``search_range`` (the paper's for the multiquadric).
    - ``cv_splits``: random half-splits per candidate (10 in the paper).
    - ``search_points``: rows used by the search, drawn at random from the
      data; the paper does not say which set it cross-validates, and the
      subsampling already needs a length scale, so the search runs first on a
      random subset as large as the model (``None``: ``n_points``, or all rows).
    - ``cv_max_outputs``: output columns the CV error is measured on (a seeded
      random subset of the non-constant ones; ``None`` = all). Matters for the
      learned Jacobian's tens of thousands of outputs.
    - ``n_farthest``: farthest points added after the rest pose (Eq. 7; the
      paper's "several").
    - ``max_candidates``: rows the greedy step may pick from (a seeded random
      pool that always keeps the rest pose); bounds memory at
      ``8 * max_candidates * n_points`` bytes. ``None`` = every row.
    - ``normalize``: standardise inputs and outputs by mean and std (the GP
      mean then reverts to the data mean, not zero, far from the data).
    - ``output_scale``: ``"per_output"`` std, or one ``"shared"`` std for all
      outputs (for outputs of one kind, like Jacobian entries). Output scaling
      changes only the error used to choose points and length scales: the
      prediction is linear in ``Y``.
    - ``seed``: for the CV halves, the search subset and the candidate pool.
    - ``progress``: show a progress bar while subsampling.
    - ``fit_threads``: BLAS threads while fitting (``None``: the library's
      default). Fitting is hundreds of small LU solves and matrix-vector
      products, which one thread does faster than two on a busy 2-core machine
      (measured 10x); prediction is untouched and uses every thread.
    """

    name = "gpr"
    kernel_params = ("kernel",)

    kernel: Kernel | None = None
    regularization: float = 1e-5
    n_points: int | None = 750
    search_length_scale: bool = True
    length_scale_range: Sequence[float] | None = None
    n_length_scales: int = 25
    cv_splits: int = 10
    search_points: int | None = None
    cv_max_outputs: int | None = 256
    n_farthest: int = 10
    max_candidates: int | None = 20_000
    normalize: bool = True
    output_scale: OutputScale = "per_output"
    seed: int = 0
    progress: bool = False
    fit_threads: int | None = 1

    repr_params = ("kernel", "regularization", "n_points")

    def _repr_fields(self) -> dict[str, Any]:
        return {**super()._repr_fields(), "kernel": repr(self._kernel())}  # None names the default

    def _kernel(self) -> Kernel:
        return self.kernel if self.kernel is not None else MultiquadricKernel()

    @property
    def search_range(self) -> tuple[float, float]:
        """The length-scale search range: ``length_scale_range``, else the kernel's."""
        chosen = self.length_scale_range
        if chosen is None:
            chosen = getattr(self._kernel(), "search_range", MultiquadricKernel.search_range)
        low, high = chosen
        return float(low), float(high)

    def _check_params(self) -> None:
        if not isinstance(self._kernel(), Kernel):
            raise ValueError(
                f"GaussianProcessRegressor: kernel must be a rigmap.regression.kernels.Kernel, "
                f"got {type(self.kernel).__name__}"
            )
        if not (np.isfinite(self.regularization) and self.regularization >= 0):
            raise ValueError(
                f"GaussianProcessRegressor: regularization must be >= 0, got {self.regularization}"
            )
        if self.n_points is not None and int(self.n_points) < 1:
            raise ValueError(
                f"GaussianProcessRegressor: n_points must be >= 1, got {self.n_points}"
            )
        low, high = self.search_range
        if not (0 < low <= high and np.isfinite(high)):
            raise ValueError(
                "GaussianProcessRegressor: length_scale_range must be (low, high) with "
                f"0 < low <= high, got {(low, high)}"
            )
        if int(self.n_length_scales) < 1 or int(self.cv_splits) < 1:
            raise ValueError(
                "GaussianProcessRegressor: n_length_scales and cv_splits must be >= 1, got "
                f"{self.n_length_scales} and {self.cv_splits}"
            )
        if self.output_scale not in ("per_output", "shared"):
            raise ValueError(
                "GaussianProcessRegressor: output_scale must be 'per_output' or 'shared', "
                f"got {self.output_scale!r}"
            )

    # ------------------------------------------------------------------ fit
    def fit(
        self,
        X: Any,
        Y: Any,
        *,
        rest_index: int = 0,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> GaussianProcessRegressor:
        """Search the length scale, subsample, and solve for the weights.

        ``rest_index`` is the row of the rest pose, where subsampling starts.
        ``rig_name`` and ``control_names`` (one per column of ``Y``) are stored
        so the model later refuses other rigs.
        """
        self._check_params()
        X, Y2 = check_training_data(X, Y, "GaussianProcessRegressor")
        n = len(X)
        if not 0 <= int(rest_index) < n:
            raise RegressionInputError(
                f"GaussianProcessRegressor.fit: rest_index must be a row of X (0..{n - 1}), "
                f"got {rest_index}"
            )
        rng = np.random.default_rng(self.seed)
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], Y2.shape[1], rig_name, control_names)
        self.output_was_vector_ = np.ndim(Y) == 1

        if self.normalize:
            self.x_mean_, self.x_std_ = column_scale(X)
            self.y_mean_, self.y_std_ = column_scale(Y2, shared=self.output_scale == "shared")
        else:
            self.x_mean_, self.x_std_ = np.zeros(X.shape[1]), np.ones(X.shape[1])
            self.y_mean_, self.y_std_ = np.zeros(Y2.shape[1]), np.ones(Y2.shape[1])
        Xn = (X - self.x_mean_) / self.x_std_
        Yn = (Y2 - self.y_mean_) / self.y_std_
        with threadpool_limits(limits=self.fit_threads, user_api="blas"):
            self._fit_standardised(Xn, Yn, int(rest_index), rng)
        if self.rcond_ < _WARN_RCOND:
            warnings.warn(
                f"GaussianProcessRegressor: the support system is nearly singular (reciprocal "
                f"condition {self.rcond_:.1e}, solver {self.solver_}); predictions may be "
                "unstable — try another regularization or length-scale range",
                RuntimeWarning,
                stacklevel=2,
            )
        return self

    def _fit_standardised(
        self, Xn: np.ndarray, Yn: np.ndarray, rest_index: int, rng: np.random.Generator
    ) -> None:
        """Length-scale search, subsampling and the final solve, on standardised data."""
        n = len(Xn)
        kernel = self._kernel()
        target = n if self.n_points is None else min(int(self.n_points), n)
        clock = time.perf_counter()
        if self.search_length_scale:
            kernel = self._search(Xn, Yn, kernel, target, rng)
        else:
            self.length_scales_ = np.array([kernel.length_scale])
            self.cv_errors_ = np.array([np.nan])
        self.kernel_ = kernel
        self.length_scale_ = kernel.length_scale
        search_s, clock = time.perf_counter() - clock, time.perf_counter()

        if target >= n:
            order = np.r_[rest_index, np.delete(np.arange(n), rest_index)]
            self.support_indices_ = order.astype(np.int64)
            self.selection_errors_ = np.empty(0)
        else:
            pool = self._candidate_pool(n, rest_index, rng)
            subsample = greedy_subsample(
                Xn[pool],
                Yn[pool],
                kernel,
                self.regularization,
                target,
                rest_index=int(np.flatnonzero(pool == rest_index)[0]),
                n_farthest=int(self.n_farthest),
                progress=self.progress,
            )
            self.support_indices_ = pool[subsample.indices]
            self.selection_errors_ = subsample.max_errors
        subsample_s, clock = time.perf_counter() - clock, time.perf_counter()
        support = self.support_indices_
        if np.array_equal(support, np.arange(n)):  # every row, in order: no copies (Jacobians)
            self.support_inputs_, support_targets = Xn, Yn
        else:
            self.support_inputs_, support_targets = Xn[support], Yn[support]
        solution = solve_regularized(
            kernel(self.support_inputs_), support_targets, self.regularization
        )
        self.weights_, self.solver_, self.rcond_ = solution
        self.fit_seconds_ = {
            "length_scale_search": search_s,
            "subsampling": subsample_s,
            "solve": time.perf_counter() - clock,
        }

    def _search(
        self, Xn: np.ndarray, Yn: np.ndarray, kernel: Kernel, target: int, rng: np.random.Generator
    ) -> Kernel:
        low, high = self.search_range
        self.length_scales_ = np.geomspace(low, high, int(self.n_length_scales))
        size = min(len(Xn), int(self.search_points) if self.search_points else target)
        rows = np.sort(rng.choice(len(Xn), size=size, replace=False))
        columns = np.arange(Yn.shape[1])
        if self.cv_max_outputs is not None and len(columns) > int(self.cv_max_outputs):
            varying = np.flatnonzero(Yn.std(axis=0) > 0)
            pool = varying if len(varying) else columns
            count = min(len(pool), int(self.cv_max_outputs))
            columns = np.sort(rng.choice(pool, size=count, replace=False))
        self.cv_errors_ = length_scale_cv_errors(
            Xn[rows],
            Yn[np.ix_(rows, columns)],
            kernel,
            self.regularization,
            self.length_scales_,
            int(self.cv_splits),
            rng,
        )
        if not np.isfinite(self.cv_errors_).any():
            raise RuntimeError(
                "GaussianProcessRegressor: every length scale in "
                f"{self.search_range} gave a non-finite validation error"
            )
        best = float(self.length_scales_[int(np.nanargmin(self.cv_errors_))])
        return kernel.with_length_scale(best)

    def _candidate_pool(self, n: int, rest_index: int, rng: np.random.Generator) -> np.ndarray:
        if self.max_candidates is None or n <= int(self.max_candidates):
            return np.arange(n)
        others = np.delete(np.arange(n), rest_index)
        drawn = rng.choice(others, size=int(self.max_candidates) - 1, replace=False)
        return np.sort(np.r_[rest_index, drawn])

    # ------------------------------------------------------------------ predict
    def predict(self, X: Any) -> np.ndarray:
        """Eq. 6 for a batch ``(M, D)`` (or one ``(D,)`` row); chunked to bound memory."""
        self._check_fitted()
        X, squeeze = self.fingerprint_.check_inputs(X, "GaussianProcessRegressor")
        out = np.empty((len(X), self.fingerprint_.output_dim))
        for start in range(0, len(X), _PREDICT_CHUNK):
            Xn = (X[start : start + _PREDICT_CHUNK] - self.x_mean_) / self.x_std_
            out[start : start + _PREDICT_CHUNK] = (
                self.kernel_(Xn, self.support_inputs_) @ self.weights_
            )
        out *= self.y_std_
        out += self.y_mean_
        if self.output_was_vector_:
            out = out[:, 0]
        return out[0] if squeeze else out

    def support_points(self) -> np.ndarray:
        """The chosen support poses in the caller's (unnormalised) units, in picking order."""
        self._check_fitted()
        return self.support_inputs_ * self.x_std_ + self.x_mean_

    def _check_fitted(self) -> None:
        if not hasattr(self, "weights_"):
            raise RuntimeError("GaussianProcessRegressor is not fitted: call fit(X, Y) first")

    # ------------------------------------------------------------------ hooks for the fit stage
    def fit_options(self, *, rest_index: int) -> dict[str, Any]:
        return {"rest_index": rest_index}  # subsampling starts from the rest pose (§4.2)

    @property
    def kernel_name(self) -> str:
        return self._kernel().label

    def describe_plan(self, rows: int) -> str:
        target = rows if self.n_points is None else min(int(self.n_points), rows)
        steps = []
        if self.search_length_scale:
            low, high = self.search_range
            search_rows = min(rows, int(self.search_points) if self.search_points else target)
            steps.append(
                f"length-scale search ({self.n_length_scales} values in [{low:g}, {high:g}] x "
                f"{self.cv_splits} half-splits on {search_rows} rows)"
            )
        if target < rows:
            steps.append(f"greedy subsampling to {target} of {rows} rows")
        steps.append("solve")
        return f"GPR ({self._kernel().name} kernel): " + ", then ".join(steps)

    def describe_result(self) -> list[str]:
        phases = self.fit_seconds_
        lines = [
            f"GPR length-scale search {phases['length_scale_search']:.1f} s -> "
            f"{self.length_scale_:.3g}; subsampling {phases['subsampling']:.1f} s -> "
            f"{len(self.support_indices_)} support points; solve {phases['solve']:.1f} s "
            f"({self.solver_}, reciprocal condition {self.rcond_:.1e})"
        ]
        if self.search_length_scale:
            curve = ", ".join(
                f"{scale:.3g}: {error:.3g}"
                for scale, error in zip(self.length_scales_, self.cv_errors_, strict=True)
            )
            lines.append(f"CV error by length scale (standardised units²): {curve}")
        return lines

    def fit_facts(self) -> dict[str, Any]:
        return {
            "gpr": {
                "length_scale": float(self.length_scale_),
                "length_scale_search": {
                    "searched": bool(self.search_length_scale),
                    "candidates": [float(v) for v in self.length_scales_],
                    "cv_errors": [float(v) for v in self.cv_errors_],
                },
                "support_points": len(self.support_indices_),
                "solver": self.solver_,
                "reciprocal_condition": float(self.rcond_),
                "phase_seconds": dict(self.fit_seconds_),
            }
        }

    # ------------------------------------------------------------------ save / load
    saved_arrays = (
        "x_mean",
        "x_std",
        "y_mean",
        "y_std",
        "support_inputs",
        "support_indices",
        "weights",
        "length_scales",
        "cv_errors",
        "selection_errors",
    )

    def _file_meta(self) -> dict[str, Any]:
        return {
            "kernel": self.kernel_.to_dict(),
            "output_was_vector": bool(self.output_was_vector_),
            "solver": self.solver_,
            "rcond": float(self.rcond_),
            "length_scale": float(self.length_scale_),
        }

    def _restore(self, meta: dict[str, Any], payload: bytes, source: str) -> None:
        arrays = arrays_from_bytes(payload, source, self.saved_arrays)
        self._restore_state(meta, arrays, source)

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON-able metadata and the arrays of a fitted model (for models that embed a GPR)."""
        self._check_fitted()
        meta = {
            "params": params_for_file(self.get_params()),
            "fingerprint": self.fingerprint_.to_dict(),
            **self._file_meta(),
        }
        return meta, {name: getattr(self, f"{name}_") for name in self.saved_arrays}

    @classmethod
    def from_state(
        cls, meta: dict[str, Any], arrays: dict[str, np.ndarray], source: str
    ) -> GaussianProcessRegressor:
        """Rebuild a fitted model from ``state()``; array shapes must match the fingerprint."""
        try:
            model = cls(**params_from_file(meta["params"], cls.kernel_params))
            model.fingerprint_ = ModelFingerprint.from_dict(meta["fingerprint"])
        except (KeyError, TypeError, ValueError) as error:
            raise ModelFileError(
                f"{source}: metadata is incomplete or invalid ({error!r})"
            ) from None
        model._restore_state(meta, arrays, source)
        return model

    def _restore_state(
        self, meta: dict[str, Any], arrays: dict[str, np.ndarray], source: str
    ) -> None:
        try:
            self.kernel_ = kernel_from_dict(meta["kernel"])
            self.length_scale_ = float(meta["length_scale"])
            self.solver_ = str(meta["solver"])
            self.rcond_ = float(meta["rcond"])
            self.output_was_vector_ = bool(meta["output_was_vector"])
        except (KeyError, TypeError, ValueError) as error:
            raise ModelFileError(
                f"{source}: metadata is incomplete or invalid ({error!r})"
            ) from None
        fingerprint = self.fingerprint_
        n_support = len(arrays["support_inputs"])
        expected = {
            "x_mean": (fingerprint.input_dim,),
            "x_std": (fingerprint.input_dim,),
            "y_mean": (fingerprint.output_dim,),
            "y_std": (fingerprint.output_dim,),
            "weights": (n_support, fingerprint.output_dim),
            "support_inputs": (n_support, fingerprint.input_dim),
        }
        for name, shape in expected.items():
            if arrays[name].shape != shape:
                raise ModelFileError(
                    f"{source}: array {name!r} has shape {arrays[name].shape}, expected {shape} "
                    "from the model's fingerprint"
                )
        for name in self.saved_arrays:
            setattr(self, f"{name}_", arrays[name])
