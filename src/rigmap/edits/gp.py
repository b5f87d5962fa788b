"""The GP predictors of §4.1 and §7.1: one RBF + noise kernel shared by every output.

"We use the same values of all three hyper-parameters for all of the target degrees of
freedom" (§7.1): the kernel ``k(x, x') = σ_f² exp(-|x - x'|² / (2ℓ²)) + σ_n² δ`` is
fitted once for all outputs by maximising the summed log marginal likelihood, from
ℓ = σ_f = 1 and σ_n = 0.1 (the paper's initialisation: log-parameters 0 and
log √0.01), with at most 100 optimiser iterations (the paper's GPML ``minimize``, a
conjugate-gradient method). Because the kernel is shared, the predictive variance is
one number per frame, shared by the outputs.

Two optimisers of the same objective (``method``):

- ``"lbfgs"`` (the default): scipy's L-BFGS-B on the three log-parameters with the
  analytic gradient, ≤ ``max_iterations`` iterations. An evaluation is one Cholesky, one
  ``potri`` inverse and lower-triangle sums (:meth:`SharedGP._objective`; half the work of
  the first implementation's full matrices, the same iterates to ~1e-4).
- ``"profile"`` (ours, opt-in): for a fixed ℓ, one eigendecomposition ``R = Q Λ Qᵀ`` of
  the RBF matrix makes the other two parameters cheap: with ``s_i`` the squared norms of
  the rows of ``QᵀY``, the objective is ``½ Σ s_i / v_i + ½ D Σ log v_i + const``,
  ``v_i = σ_f² λ_i + σ_n² + jitter``, O(N) per evaluation (a grid, then L-BFGS-B in
  ``σ_f², σ_n²``). The profiled objective of ``log ℓ`` is searched from its derivative —
  by the envelope theorem the partial ``−½ tr((ααᵀ − D K⁻¹) ∂K/∂log ℓ)`` at the inner
  optimum, ``K⁻¹`` from the eigenbasis — stepping downhill from ℓ = 1 until the slope
  changes sign, then Brent's root finder (≈ 10 eigendecompositions, ≈ 0.3 s each at
  1 100 frames). It finds a true stationary point (the 3-D search stops early, "ABNORMAL"
  line searches, when the noise falls to the jitter) of higher likelihood, but on the
  noiseless procedural edits that point is a different local optimum: a shorter ℓ and
  the noise at the jitter, which generalises worse (measured on the biped's
  ``arms_forward_walking``: held-out edit error 0.079 std² against the 3-D search's
  1.5e-5). Hence not the default.

Written here rather than taken from scikit-learn (its ``GaussianProcessRegressor``
fits per call with restarts and has no shared multi-output likelihood with our
initialisation and iteration cap) or GPyTorch (batch-independent outputs would each get
their own hyper-parameters). Outputs are centred on their training mean (ours).

Inputs (``input_scale``): the paper's kinematic features are joint positions "in 3D
space" (§4.5), so the RBF's distance is a distance between skeletons. The default,
``"global"``, keeps that geometry: the columns are centred and all divided by *one*
number, the root mean square of their standard deviations (ours: it only conditions
the optimiser's start, ℓ = 1). ``"column"`` divides each column by its own standard
deviation, as the first implementation did; that is not a skeleton distance: a
coordinate that barely moves in the examples (a joint held still in the walk and the
stand) is blown up to unit spread, and its small, irrelevant differences on another
clip then dominate the distance, and even neighbouring frames end up far apart
against the starting ℓ = 1, where the likelihood's slope in ℓ vanishes. Measured on
the biped's ``arm_swing`` as the stages run it (examples: a walk and a stand; outputs
in the library's training-std units): per column, the kinematic GP stopped at ℓ = 2.5
with noise above signal and predicted no edit at all on a held-out walk (transfer
ρ = 0.00, the same predictive variance on every clip); with one global scale ℓ = 42,
ρ = 0.82 on the held-out walk, and the variance 0.0000 on the walk and the stand
against 0.0011–0.0014 on the reach, crouch, wave, pick-up, kick and point clips. (Which
optimum the per-column fit reaches depends on the output scale: on outputs about ten
times larger it also carried the edit.)

Linear algebra runs on one BLAS thread: at these sizes (a few hundred to a thousand
frames) threads cost more than they save, badly so on a loaded machine (measured on the
shared 2-core box: a 177² Cholesky 0.6 ms on one thread, 125 ms on two). The pairwise
squared distances of the training inputs are computed once per fit, not per iteration.
The objective's ``K⁻¹`` (``potri``), ``K⁻¹Y`` (``potrs``) and ``ααᵀ`` (``syrk``) go
through :mod:`rigmap.edits.nogil`, the same LAPACK/BLAS routines called without the GIL
(SciPy's wrappers of these three hold it), so :class:`rigmap.edits.propagation.EditModel`'s
two fits, one per thread, no longer take turns in them; the values are bit-identical.

Erratum: the paper's Eqs 3–4 write the Gaussian as ``c exp((Y − μ)ᵀ Σ⁻¹ (Y − μ))``; the
exponent needs a factor −½.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh, lapack
from scipy.optimize import brentq, minimize
from threadpoolctl import threadpool_limits

from rigmap.edits import nogil
from rigmap.errors import RigmapError
from rigmap.gp.distances import expanded_squared_distances
from rigmap.gp.kernels import rbf, rbf_d_log_lengthscale
from rigmap.gp.likelihood import negative_log_marginal_likelihood
from rigmap.gp.solve import JITTER as _JITTER
from rigmap.gp.solve import add_noise, cholesky, cholesky_solve

MAX_ITERATIONS = 100  # §7.1
INITIAL = {"length_scale": 1.0, "signal": 1.0, "noise": 0.1}  # §7.1
METHODS = ("profile", "lbfgs")
INPUT_SCALES = ("global", "column")
# the profile fit's search ranges (ours): log ℓ on standardised inputs, the starting
# grid of log(σ_n²/σ_f²), and log σ_n² (below ≈ 1e-20 the jitter is all the noise)
_LOG_LENGTH_RANGE = (np.log(1e-3), np.log(1e5))
_RATIO_RANGE = (-30.0, 12.0)
_LOG_NOISE2_RANGE = (-46.0, 12.0)


class GPInputError(RigmapError, ValueError):
    """Training or test data a GP predictor cannot use; says which array and why."""


@dataclass(frozen=True)
class Prediction:
    """Predictive means ``(N, D)`` and the shared variance ``(N,)`` (output units²)."""

    mean: np.ndarray
    variance: np.ndarray


class SharedGP:
    """Exact GP regression with one RBF + noise kernel for all outputs.

    ``fit(X (N, P), Y (N, D))`` maximises the marginal likelihood over
    ``log ℓ, log σ_f, log σ_n``; ``predict(X)`` gives means and the shared variance
    (noise included: the variance of a new observation). ``center=False`` keeps the
    prior mean at zero instead of the training mean: far from the data an edit's offset
    then falls back to no edit. ``input_scale``: ``"global"`` or ``"column"`` (module
    docstring).
    """

    def __init__(
        self,
        max_iterations: int = MAX_ITERATIONS,
        optimize: bool = True,
        center: bool = True,
        method: str = "lbfgs",
        input_scale: str = "global",
    ):
        if method not in METHODS:
            raise GPInputError(f"unknown GP fitting method {method!r}; expected one of {METHODS}")
        if input_scale not in INPUT_SCALES:
            raise GPInputError(
                f"unknown GP input scale {input_scale!r}; expected one of {INPUT_SCALES}"
            )
        self.max_iterations = max_iterations
        self.optimize = optimize
        self.center = center
        self.method = method
        self.input_scale = input_scale

    # --- fitting -----------------------------------------------------------------------
    def fit(self, X, Y, *, initial: dict | None = None) -> SharedGP:
        with threadpool_limits(limits=1, user_api="blas"):
            return self._fit(X, Y, initial)

    def _fit(self, X, Y, initial: dict | None) -> SharedGP:
        X, Y = _checked(X, "X"), _checked(Y, "Y")
        if len(X) != len(Y) or len(X) < 2:
            raise GPInputError(
                f"expected X and Y with the same N >= 2 rows, got {X.shape}, {Y.shape}"
            )
        self.x_mean_ = X.mean(axis=0)
        self.x_std_ = input_scales(X, self.input_scale)
        self.y_mean_ = Y.mean(axis=0) if self.center else np.zeros(Y.shape[1])
        self.X_ = (X - self.x_mean_) / self.x_std_
        self.Y_ = Y - self.y_mean_
        self._sq = expanded_squared_distances(self.X_, self.X_)
        n = len(self.X_)
        self._lower = np.tril(np.full((n, n), 2.0), -1) + np.eye(n)  # see _objective
        self.__dict__.pop("_work", None)  # _objective's work arrays: made for these data
        start = {**INITIAL, **(initial or {})}
        theta = np.log([start["length_scale"], start["signal"], start["noise"]])
        self.iterations_ = self.evaluations_ = 0
        if self.optimize and self.method == "lbfgs":
            result = minimize(
                self._objective,
                theta,
                jac=True,
                method="L-BFGS-B",
                options={"maxiter": self.max_iterations},
            )
            theta, self.iterations_ = result.x, int(result.nit)
        elif self.optimize:
            theta = self._fit_profile(theta[0])
        self.__dict__.pop("_work", None)  # n² arrays the fitted GP does not need
        self.length_scale_, self.signal_, self.noise_ = (float(v) for v in np.exp(theta))
        self._L = cholesky(self._gram(theta))
        self._alpha = cholesky_solve(self._L, self.Y_)
        self.log_marginal_likelihood_ = -float(
            negative_log_marginal_likelihood(self.Y_, self._alpha, self._L)
        )
        return self

    def _gram(self, theta) -> np.ndarray:
        length, signal, noise = np.exp(theta)
        return add_noise(rbf(self._sq, signal**2, length**2), noise**2, _JITTER)

    def _objective(self, theta) -> tuple[float, np.ndarray]:
        """Negative summed log marginal likelihood and its gradient in log-parameters.

        The gradient ``−½ Σ (ααᵀ − D K⁻¹) ∘ ∂K`` sums over the lower triangle only (every
        matrix in it is symmetric): ``K⁻¹`` from LAPACK ``potri`` and ``ααᵀ`` from
        ``syrk`` fill just that half, and ``self._lower`` (2 below the diagonal, 1 on it,
        0 above) weighs it back to the whole sum — half the work of full matrices. The
        RBF and Gram matrices go into arrays made once per fit (``_work``, with ``-½ sq``;
        dropped when the fit ends): the same operations in the same order as on fresh
        arrays each call (bit-identical values), about 5 % less CPU per evaluation at
        1 100 frames (measured in s28: 78.6 → 74.7 ms and 76.7 → 73.0 ms). They are
        Fortran-ordered, so ``dpotrf`` factors ``K`` in place (SciPy's ``cho_factor``
        copied it), and ``dpotrs``, ``dpotri`` and ``dsyrk`` run without the GIL
        (:mod:`rigmap.edits.nogil`): the same values as SciPy's wrappers, bit for bit."""
        with np.errstate(over="ignore"):
            length, signal, noise = np.exp(theta)
            scales = np.array([length**2, signal**2, noise**2])
        if not (np.isfinite(scales).all() and scales[0] > 0):
            return 1e300, np.zeros(3)  # a line search's step out of range: reject it
        d = self.Y_.shape[1]
        sq = self._sq
        work = self.__dict__.get("_work")
        if work is None or work[0].shape != sq.shape:
            # Fortran order: LAPACK works on K in place (SciPy would copy a C array)
            half_sq = np.asfortranarray(-0.5 * sq)
            work = self._work = (half_sq, np.empty_like(half_sq), np.empty_like(half_sq))
        half_sq, gram, K = work
        np.divide(half_sq, length**2, out=gram)  # −½ sq / ℓ²
        np.exp(gram, out=gram)  # rigmap.gp.kernels.rbf, in place
        gram *= signal**2
        np.copyto(K, gram)
        add_noise(K, noise**2, _JITTER)
        factor, info = lapack.dpotrf(K, lower=1, overwrite_a=1, clean=0)
        if info != 0:
            return 1e300, np.zeros(3)
        A = nogil.potrs_lower(factor, self.Y_)  # K⁻¹ Y
        value = float(negative_log_marginal_likelihood(self.Y_, A, factor))
        if nogil.potri_lower(factor) != 0:  # K⁻¹ (lower half) in place of the factor
            return 1e300, np.zeros(3)
        inverse = factor
        inner = nogil.syrk_lower(A)  # ααᵀ, lower half (the upper stays 0)
        inverse *= d
        inner -= inverse  # (ααᵀ − D K⁻¹); above the diagonal: ignored
        trace = float(np.trace(inner))
        inner *= gram
        inner *= self._lower  # (ααᵀ − D K⁻¹) ∘ rbf, weighted to the whole sum
        gradient = np.array(
            [
                -0.5 * float(np.vdot(inner, sq)) / length**2,  # ∂K/∂log ℓ = rbf ∘ sq / ℓ²
                -float(inner.sum()),  # ∂K/∂log σ_f = 2 rbf
                -(noise**2) * trace,  # ∂K/∂log σ_n = 2 σ_n² I
            ]
        )
        return value, gradient

    def _fit_profile(self, log_length: float) -> np.ndarray:
        """``log ℓ, log σ_f, log σ_n`` maximising the likelihood, ℓ searched with the
        other two profiled out (module docstring); sets ``iterations_`` (steps of the ℓ
        search) and ``evaluations_`` (eigendecompositions)."""
        n, d = self.Y_.shape
        inner: dict[float, tuple[float, float]] = {}
        values_at: dict[float, float] = {}

        def slope(u: float) -> float:
            """``∂/∂ log ℓ`` of the profiled objective at ``log ℓ = u``."""
            length = float(np.exp(u))
            unit = rbf(self._sq, 1.0, length**2)
            eigenvalues, Q = eigh(unit, driver="evd", check_finite=False)
            eigenvalues = np.maximum(eigenvalues, 0.0)
            projected = Q.T @ self.Y_
            signal2, noise2, value = _profile_signal_noise(eigenvalues, (projected**2).sum(1), d)
            values = signal2 * eigenvalues + noise2 + _JITTER  # the eigenvalues of K
            alpha = Q @ (projected / values[:, None])  # K⁻¹ Y
            dK = rbf_d_log_lengthscale(signal2 * unit, self._sq, length**2)  # ∂K/∂log ℓ
            trace = float(((Q * (dK @ Q)).sum(axis=0) / values).sum())  # tr(K⁻¹ ∂K)
            inner[u] = (signal2, noise2)
            values_at[u] = value + 0.5 * n * d * np.log(2 * np.pi)
            return -0.5 * (float((alpha * (dK @ alpha)).sum()) - d * trace)

        u, steps = _descend_to_root(
            slope, float(log_length), _LOG_LENGTH_RANGE, self.max_iterations
        )
        if u not in inner:
            slope(u)
        self.iterations_, self.evaluations_ = steps, len(inner)
        signal2, noise2 = inner[u]
        return np.array([u, 0.5 * np.log(signal2), 0.5 * np.log(noise2)])

    @property
    def prior_variance(self) -> float:
        """``σ_f² + σ_n²``: the predictive variance far from every example."""
        return self.signal_**2 + self.noise_**2

    # --- saving ------------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        """Plain arrays that rebuild the fitted GP (:meth:`from_state`); no pickle."""
        names = ("X_", "Y_", "x_mean_", "x_std_", "y_mean_")
        arrays = {name: getattr(self, name) for name in names}
        arrays["factor"], arrays["alpha"] = self._L, self._alpha
        arrays["hyper"] = np.array(
            [
                self.length_scale_,
                self.signal_,
                self.noise_,
                self.log_marginal_likelihood_,
                self.iterations_,
            ]
        )
        return arrays

    @classmethod
    def from_state(cls, arrays) -> SharedGP:
        gp = cls(optimize=False)
        for name in ("X_", "Y_", "x_mean_", "x_std_", "y_mean_"):
            setattr(gp, name, np.asarray(arrays[name], dtype=np.float64))
        hyper = np.asarray(arrays["hyper"], dtype=np.float64)
        gp.length_scale_, gp.signal_, gp.noise_, gp.log_marginal_likelihood_ = map(float, hyper[:4])
        gp.iterations_ = int(hyper[4])
        # the factor itself, not a refactorisation: a near-noiseless K is ill-conditioned
        gp._L = np.asarray(arrays["factor"], dtype=np.float64)
        gp._alpha = np.asarray(arrays["alpha"], dtype=np.float64)
        return gp

    # --- predicting --------------------------------------------------------------------
    def predict(self, X) -> Prediction:
        with threadpool_limits(limits=1, user_api="blas"):
            return self._predict(X)

    def _predict(self, X) -> Prediction:
        if not hasattr(self, "_alpha"):
            raise GPInputError("this SharedGP is not fitted yet: call fit(X, Y) first")
        X = (_checked(X, "X") - self.x_mean_) / self.x_std_
        if X.shape[1] != self.X_.shape[1]:
            raise GPInputError(
                f"X has {X.shape[1]} columns, the GP was fitted on {self.X_.shape[1]}"
            )
        k = rbf(expanded_squared_distances(X, self.X_), self.signal_**2, self.length_scale_**2)
        mean = k @ self._alpha + self.y_mean_
        v = cholesky_solve(self._L, k.T)
        variance = self.signal_**2 + self.noise_**2 - np.einsum("ij,ji->i", k, v)
        return Prediction(mean, np.maximum(variance, self.noise_**2))


def input_scales(X: np.ndarray, how: str) -> np.ndarray:
    """What each input column is divided by: one number for all (``"global"``, the RMS of
    the columns' standard deviations) or each column's own (``"column"``); 1 where there
    is no spread."""
    std = X.std(axis=0)
    if how == "global":
        std = np.full_like(std, np.sqrt(np.mean(std**2)))
    elif how != "column":
        raise GPInputError(f"unknown input scale {how!r}; expected one of {INPUT_SCALES}")
    return np.where(std > 0, std, 1.0)


def _profile_signal_noise(eigenvalues: np.ndarray, s: np.ndarray, d: int):
    """``σ_f², σ_n²`` minimising the objective at a fixed ℓ and that minimum (without
    its constant): ``½ Σ s_i / v_i + ½ D Σ log v_i`` with ``v_i = σ_f² λ_i + σ_n² +
    jitter``, O(N) per evaluation. Start: the best of a grid over ``log(σ_n²/σ_f²)`` with
    σ_f² in closed form (exact without the jitter), then L-BFGS-B on ``log σ_f²,
    log σ_n²`` with the analytic gradient (the jitter included)."""
    n = len(eigenvalues)

    def objective(z: np.ndarray) -> tuple[float, np.ndarray]:
        signal2, noise2 = np.exp(z)
        v = signal2 * eigenvalues + noise2 + _JITTER
        w = 0.5 * (d / v - s / v**2)
        value = 0.5 * float((s / v).sum()) + 0.5 * d * float(np.log(v).sum())
        return value, np.array([signal2 * float(w @ eigenvalues), noise2 * float(w.sum())])

    best = None
    for log_ratio in np.linspace(*_RATIO_RANGE, 43):
        shifted = eigenvalues + np.exp(log_ratio)
        signal2 = float((s / shifted).sum()) / (n * d)
        z = np.log([signal2, signal2 * np.exp(log_ratio)])
        value = objective(z)[0]
        if best is None or value < best[0]:
            best = (value, z)
    bounds = [(None, None), _LOG_NOISE2_RANGE]
    z0 = np.clip(best[1], [-np.inf, bounds[1][0]], [np.inf, bounds[1][1]])
    found = minimize(
        objective,
        z0,
        jac=True,
        method="L-BFGS-B",
        bounds=bounds,
        options={"ftol": 1e-15, "gtol": 1e-9, "maxiter": 500},
    )
    z, value = (found.x, found.fun) if found.fun <= best[0] else (best[1], best[0])
    return float(np.exp(z[0])), float(np.exp(z[1])), float(value)


def _descend_to_root(slope, u: float, bounds: tuple[float, float], max_steps: int):
    """A local minimum of a smooth scalar function from its derivative alone: steps
    downhill from ``u`` (secant-extrapolated, 0.5–3 in log ℓ; ours) until the slope
    changes sign, then Brent's root finder on the slope in that bracket (``xtol``
    1e-3 in log ℓ, ours). Returns the point and the number of steps; a bound is returned
    when the slope never changes sign before it."""
    low, high = bounds
    ga = slope(u)
    steps, step = 1, 1.0
    while steps < max_steps and ga != 0.0:
        direction = -np.sign(ga)
        v = float(np.clip(u + direction * step, low, high))
        gb = slope(v)
        steps += 1
        if np.sign(gb) != np.sign(ga):
            a, b = sorted((u, v))
            root, info = brentq(
                slope,
                a,
                b,
                xtol=1e-3,
                maxiter=max(max_steps - steps, 1),
                full_output=True,
                disp=False,
            )
            return float(root), steps + info.function_calls
        if v in (low, high):
            return v, steps
        extrapolated = abs((v - u) * gb / (ga - gb)) if ga != gb else 2.0 * step
        step = float(np.clip(1.5 * extrapolated, 0.5, 3.0))
        u, ga = v, gb
    return u, steps


def _checked(values, name: str) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if values.ndim != 2:
        raise GPInputError(f"{name} must be a 2-D array (rows, columns), got shape {values.shape}")
    if not np.isfinite(values).all():
        row, col = np.argwhere(~np.isfinite(values))[0]
        raise GPInputError(f"{name} has a non-finite value at row {row}, column {col}")
    return values
