"""A GPLVM with dynamics and connectivity priors, fitted by MAP (Bailey et al. 2016, §4.3).

The model (Eqs 4–7): PCA outputs ``Y`` ``(N, d)`` are ``d`` independent GP draws over
latent points ``X`` ``(N, q)`` with an RBF + white kernel (Eq 5). ``X`` has two priors:
the dynamics prior of Lawrence's simple hierarchical model (Eq 6), each latent column a
GP over frame time with an RBF kernel that is block-diagonal per segment; and Levine et
al.'s (2012) connectivity prior, ``ψ_C = w_c Σ_ij ln K^d_ij`` with the graph diffusion
kernel ``K^d = exp(β H)``, ``H = −T^{-1/2} L T^{-1/2}`` the negated normalised Laplacian
of the complete graph with weights ``‖x_i − x_j‖^{-p}``. ``X`` and the kernel's three
hyper-parameters are a MAP estimate (Eq 7); the dynamics hyper-parameters are set by
hand and not optimised, as in the paper. Measured on two takes of one curve (tests):
ψ_C pulls a distant take into contact with the other, but not point on point — a
near-duplicate pair dominates the ‖·‖⁻⁴ graph of its two nodes and starves the rest of
the diffusion, so the prior settles the takes at about their frame spacing.

Errata followed here: Eq 4 lacks a log — the term is ``−(d/2) ln|K_x|``; Eq 8's
variance is ``k(x, x) − k_xᵀ K_x⁻¹ k_x`` (the paper prints ``K_x``, not its inverse).

Why torch and not a library: GPyTorch's GPLVM is a sparse variational model (inducing
points, a variational posterior over ``X``), not this exact MAP model with these two
priors; GPy fits the exact model without them. The objective here is a few dense
float64 matrix operations, so autograd gives its exact gradient and L-BFGS (the paper
used scaled conjugate gradient) optimises it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from rigmap.gp.distances import difference_squared_distances
from rigmap.gp.kernels import rbf_gram, rbf_input_gradient
from rigmap.gp.likelihood import negative_log_marginal_likelihood
from rigmap.gp.solve import add_noise, cholesky, cholesky_solve, solve_lower
from rigmap.latent.errors import LatentInputError
from rigmap.torch_threads import torch_threads

DTYPE = torch.float64


@dataclass(frozen=True)
class GPLVMSettings:
    """What the fit uses; "ours" marks values the paper does not give."""

    latent_dim: int = 3  # the paper's
    dynamics_lengthscale_s: float = 0.25  # ours: about six frames at 24 fps
    dynamics_variance: float = 1.0  # ours; X is initialised at unit scale to match
    dynamics_noise: float = 1e-2  # ours: white term that keeps K_t invertible
    connectivity: bool = True
    connectivity_weight: float = 1.0  # ours: w_c, applied as w_c / N so it grows like Eq 4
    connectivity_beta: float = 2.0  # ours: the diffusion time β
    connectivity_power: float = 4.0  # p; §5.3 uses 4 for its graph "like the prior's"
    connectivity_epsilon: float = 1e-3  # ours: ‖·‖ floor so coincident points stay finite
    dynamics: bool = True
    max_iter: int = 300  # ours
    noise_floor: float = 1e-6  # ours: σ_white² ≥ floor × data variance
    min_segment_frames: int = 4  # ours: fewer frames carry no dynamics to model
    seed: int = 0  # only pads the initialisation when q > d
    threads: int | None = 1  # ours: see `torch_threads`; None keeps torch's setting

    def __post_init__(self) -> None:
        if self.latent_dim < 1:
            raise LatentInputError(f"latent_dim must be ≥ 1, got {self.latent_dim}")
        for name in ("dynamics_lengthscale_s", "dynamics_variance", "connectivity_beta"):
            if not getattr(self, name) > 0:
                raise LatentInputError(f"{name} must be > 0, got {getattr(self, name)}")


def dynamics_kernel(times: np.ndarray, segments: np.ndarray, s: GPLVMSettings) -> torch.Tensor:
    """``K_t``: an RBF over frame time, zero between frames of different segments."""
    t = torch.as_tensor(times, dtype=DTYPE)[:, None]
    K = rbf_gram(t, t, s.dynamics_variance, s.dynamics_lengthscale_s**2)
    same = torch.as_tensor(segments[:, None] == segments[None, :])
    K = torch.where(same, K, torch.zeros((), dtype=DTYPE))
    return add_noise(K, s.dynamics_noise * s.dynamics_variance)


def diffusion_log_kernel(X: torch.Tensor, beta: float, power: float, eps: float) -> torch.Tensor:
    """``ln K^d`` ``(N, N)`` for the complete graph on ``X`` with weights ``‖x_i − x_j‖^{-p}``.

    ``K^d = exp(−β) exp(β A)`` with ``A = T^{-1/2} W T^{-1/2}`` (so ``H = A − I``). ``A`` is
    non-negative, so the Taylor series of ``exp(βA)`` has no cancellation and every entry,
    however small, keeps its relative accuracy and a finite log; ``torch.linalg.matrix_exp``
    on ``βH`` (negative diagonal) would lose the small entries. Scaling and squaring keeps
    the series short: ``‖βA / 2^s‖ ≤ 1/2`` (the spectral radius of ``A`` is 1); the
    series itself is evaluated by Paterson–Stockmeyer (:func:`_exp_series`).
    """
    n = len(X)
    d2 = difference_squared_distances(X, X)
    W = (d2 + eps * eps).pow(-0.5 * power) * (1.0 - torch.eye(n, dtype=X.dtype))
    r = W.sum(1).rsqrt()
    A = r[:, None] * W * r[None, :]
    squarings = max(0, math.ceil(math.log2(2.0 * beta)))
    M = (beta / 2**squarings) * A
    E = _exp_series(M)
    for _ in range(squarings):
        E = E @ E
    return torch.log(E) - beta


def _exp_series(M: torch.Tensor) -> torch.Tensor:
    """``Σ_{k≤15} M^k / k!`` for ``‖M‖ ≤ 1/2`` (tail ``0.5^16/16! ≈ 7e-19``) by
    Paterson–Stockmeyer: ``M², M³, M⁴``, then Horner in ``M⁴`` over blocks of four
    terms — 6 matrix products instead of Horner's 15 (and half the backward pass:
    this is what made the connectivity prior ~90 % of the fit). Every coefficient
    and every entry of ``M`` is non-negative, so no term cancels another."""
    eye = torch.eye(len(M), dtype=M.dtype)
    M2 = M @ M
    powers = (eye, M, M2, M2 @ M)
    M4 = M2 @ M2
    c = [1.0 / math.factorial(k) for k in range(16)]

    def block(j: int) -> torch.Tensor:
        return sum(c[4 * j + i] * powers[i] for i in range(4))

    E = block(3)
    for j in (2, 1, 0):
        E = block(j) + E @ M4
    return E


class GPLVM:
    """The fitted model: latent points ``X``, kernel hyper-parameters, and the GP mean map.

    ``fit(Y, segments, times)``; then ``mean``/``variance`` at latent points (Eq 8) and
    ``project`` of new outputs back into the latent space (Eq 15).
    """

    def __init__(self, settings: GPLVMSettings | None = None):
        self.settings = settings or GPLVMSettings()
        self.X: np.ndarray | None = None
        self.history: list[float] = []  # objective at every evaluation
        self.iterations = 0  # L-BFGS iterations of the last fit
        self.converged = False

    # --- the objective -------------------------------------------------------------
    def setup(self, Y, segments, times) -> tuple[torch.Tensor, torch.Tensor]:
        """Validate the training set and build the fixed parts of the objective.
        Returns the initial ``(X, log_hyper)``: PCA columns at unit scale (ours: one
        scalar for all columns, so the initial shape is the paper's first rows of ``Y``)."""
        s = self.settings
        Y = np.asarray(Y, dtype=np.float64)
        if Y.ndim != 2 or len(Y) < 2:
            raise LatentInputError(f"GPLVM outputs must be (N ≥ 2, d), got shape {Y.shape}")
        if not np.isfinite(Y).all():
            row = int(np.argwhere(~np.isfinite(Y))[0, 0])
            raise LatentInputError(f"GPLVM outputs have non-finite values (first at frame {row})")
        segments = np.asarray(segments)
        times = np.asarray(times, dtype=np.float64)
        if segments.shape != (len(Y),) or times.shape != (len(Y),):
            raise LatentInputError(
                f"segments {segments.shape} and times {times.shape} must both be ({len(Y)},)"
            )
        if not np.isfinite(times).all():
            raise LatentInputError("frame times have non-finite values")
        labels, counts = np.unique(segments, return_counts=True)
        pairs = zip(labels, counts, strict=True)
        # np.asarray(…).item(): a numpy scalar (int segments) or a take's name (object array)
        short = [(np.asarray(lab).item(), int(c)) for lab, c in pairs if c < s.min_segment_frames]
        if short:
            raise LatentInputError(
                f"segments with fewer than {s.min_segment_frames} frames: {short[:5]}"
            )
        self.Y = torch.as_tensor(Y, dtype=DTYPE)
        self.segments, self.times = segments, times
        self.data_variance = float(Y.var(axis=0).mean()) or 1.0
        q, d = s.latent_dim, Y.shape[1]
        X0 = Y[:, : min(q, d)] - Y[:, : min(q, d)].mean(0)
        X0 = X0 / (X0.std() or 1.0)
        if q > d:  # ours: pad with small seeded noise so the extra dimensions can move
            rng = np.random.default_rng(s.seed)
            X0 = np.hstack([X0, 1e-2 * rng.standard_normal((len(Y), q - d))])
        if s.dynamics:
            Kt = dynamics_kernel(times, segments, s)
            self._Kt_chol = cholesky(Kt)
        log_hyper = torch.tensor(
            [math.log(self.data_variance), 0.0, math.log(1e-2 * self.data_variance)], dtype=DTYPE
        )  # ours: σ_rbf² = data variance, l = 1, σ_white² = 1 % of it
        return torch.as_tensor(X0, dtype=DTYPE), log_hyper

    def hyper(self, log_hyper: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(σ_rbf², l², σ_white²)`` from their logs, with the white-noise floor."""
        floor = self.settings.noise_floor * self.data_variance
        return log_hyper[0].exp(), log_hyper[1].exp(), log_hyper[2].exp() + floor

    def objective(self, X: torch.Tensor, log_hyper: torch.Tensor) -> torch.Tensor:
        """Negative log posterior, −(Eq 7), up to the constant ``ln|K_t|`` term."""
        s = self.settings
        n = len(self.Y)
        variance, ls2, white = self.hyper(log_hyper)
        L = cholesky(add_noise(rbf_gram(X, X, variance, ls2), white))
        loss = negative_log_marginal_likelihood(self.Y, cholesky_solve(L, self.Y), L)
        if s.dynamics:
            v = solve_lower(self._Kt_chol, X)
            loss = loss + 0.5 * (v * v).sum()
        if s.connectivity:
            logK = diffusion_log_kernel(
                X, s.connectivity_beta, s.connectivity_power, s.connectivity_epsilon
            )
            loss = loss - (s.connectivity_weight / n) * logK.sum()
        return loss

    # --- fitting ---------------------------------------------------------------------
    def fit(self, Y, segments, times) -> GPLVM:
        """MAP estimate of ``X`` and the kernel hyper-parameters by L-BFGS from PCA."""
        with torch_threads(self.settings.threads):
            return self._fit(Y, segments, times)

    def _fit(self, Y, segments, times) -> GPLVM:
        X0, h0 = self.setup(Y, segments, times)
        X = X0.clone().requires_grad_(True)
        h = h0.clone().requires_grad_(True)
        opt = torch.optim.LBFGS(
            [X, h],
            lr=1.0,
            max_iter=self.settings.max_iter,
            history_size=20,
            tolerance_grad=1e-7,
            tolerance_change=1e-12,
            line_search_fn="strong_wolfe",
        )
        self.history = []

        def closure():
            opt.zero_grad()
            loss = self.objective(X, h)
            loss.backward()
            self.history.append(float(loss.detach()))
            return loss

        opt.step(closure)
        self.iterations = int(opt.state_dict()["state"][0]["n_iter"])
        self.converged = self.iterations < self.settings.max_iter  # stopped on a tolerance
        self._finish(X.detach(), h.detach())
        return self

    def _finish(self, X: torch.Tensor, log_hyper: torch.Tensor) -> None:
        variance, ls2, white = self.hyper(log_hyper)
        self._X = X
        self.log_hyper = log_hyper
        self._L = cholesky(add_noise(rbf_gram(X, X, variance, ls2), white))
        self._alpha = cholesky_solve(self._L, self.Y)  # K⁻¹ Y, precomputed (§4.4)
        self.X = X.numpy().copy()
        self.kernel_variance, self.lengthscale2, self.white_variance = (
            float(variance),
            float(ls2),
            float(white),
        )

    # --- the map back (Eq 8) -------------------------------------------------------
    def _check_fitted(self) -> None:
        if self.X is None:
            raise LatentInputError("the GPLVM is not fitted yet: call fit() first")

    def _latent(self, Xs) -> torch.Tensor:
        if isinstance(Xs, torch.Tensor):
            Xs = Xs.to(DTYPE)
        else:
            Xs = torch.as_tensor(np.asarray(Xs, dtype=np.float64), dtype=DTYPE)
        if Xs.ndim != 2 or Xs.shape[1] != self._X.shape[1]:
            raise LatentInputError(
                f"latent points must be (M, {self._X.shape[1]}), got {tuple(Xs.shape)}"
            )
        return Xs

    def mean_t(self, Xs: torch.Tensor) -> torch.Tensor:
        """Eq 8's mean ``k_xᵀ K_x⁻¹ Y`` in torch (differentiable in ``Xs``)."""
        return rbf_gram(Xs, self._X, self.kernel_variance, self.lengthscale2) @ self._alpha

    def mean(self, Xs) -> np.ndarray:
        """The most likely outputs ``(M, d)`` at latent points ``(M, q)`` (Eq 8)."""
        self._check_fitted()
        with torch.no_grad():
            return self.mean_t(self._latent(Xs)).numpy()

    def variance(self, Xs, *, include_noise: bool = False) -> np.ndarray:
        """Eq 8's variance ``k(x, x) − k_xᵀ K_x⁻¹ k_x`` ``(M,)``, shared by every output."""
        self._check_fitted()
        with torch.no_grad():
            Ks = rbf_gram(self._latent(Xs), self._X, self.kernel_variance, self.lengthscale2)
            v = solve_lower(self._L, Ks.T)
            var = self.kernel_variance - (v * v).sum(0)
            if include_noise:
                var = var + self.white_variance
            return var.clamp_min(0.0).numpy()

    # --- projection (Eq 15) --------------------------------------------------------
    def mean_and_jacobian(self, Xs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Eq 8's mean ``(M, d)`` and its Jacobian in ``x`` ``(M, d, q)``, in closed form:
        ``∂k_i/∂x = −k_i (x − x_i) / l²``."""
        Ks = rbf_gram(Xs, self._X, self.kernel_variance, self.lengthscale2)
        dK = rbf_input_gradient(Ks, Xs[:, None, :] - self._X[None], self.lengthscale2)
        return Ks @ self._alpha, torch.einsum("mnq,nd->mdq", dK, self._alpha)

    def project(self, Ys, *, max_iter: int = 100) -> np.ndarray:
        """Latent points ``(M, q)`` whose GP means best reproduce outputs ``Ys`` ``(M, d)``:
        ``argmin_x ‖y − k_xᵀ K⁻¹ Y‖²`` (Eq 15), each started from the latent point of the
        nearest training output (the objective is multi-modal and flat far from the data,
        §5.2). Levenberg–Marquardt per pose (ours; the paper used scaled conjugate
        gradient): q ≤ 5 unknowns each, so every pose gets its own damping and stops on
        its own, all in one batch."""
        self._check_fitted()
        Ys = np.asarray(Ys, dtype=np.float64)
        d = self.Y.shape[1]
        if Ys.ndim != 2 or Ys.shape[1] != d:
            raise LatentInputError(f"outputs to project must be (M, {d}), got {Ys.shape}")
        if not np.isfinite(Ys).all():
            raise LatentInputError("outputs to project have non-finite values")
        with torch_threads(self.settings.threads), torch.no_grad():
            return self._levenberg_marquardt(torch.as_tensor(Ys, dtype=DTYPE), max_iter)

    def _levenberg_marquardt(self, target: torch.Tensor, max_iter: int) -> np.ndarray:
        x = self._X[torch.cdist(target, self.Y).argmin(1)].clone()
        f, J = self.mean_and_jacobian(x)
        cost = (f - target).pow(2).sum(1)
        damping = torch.full((len(x),), 1e-3, dtype=DTYPE)
        tol = 1e-10 * (1.0 + float(self._X.abs().max()))  # ours: step size that counts as done
        active = torch.ones(len(x), dtype=torch.bool)
        for _ in range(max_iter):
            JtJ = J.transpose(1, 2) @ J
            g = (J.transpose(1, 2) @ (f - target)[..., None])[..., 0]
            scale = torch.diagonal(JtJ, dim1=1, dim2=2) + 1e-12
            step = torch.linalg.solve(JtJ + damping[:, None, None] * torch.diag_embed(scale), g)
            step = torch.where(active[:, None], step, torch.zeros_like(step))
            x_new = x - step
            f_new, J_new = self.mean_and_jacobian(x_new)
            cost_new = (f_new - target).pow(2).sum(1)
            better = active & (cost_new < cost)
            x = torch.where(better[:, None], x_new, x)
            f = torch.where(better[:, None], f_new, f)
            J = torch.where(better[:, None, None], J_new, J)
            cost = torch.where(better, cost_new, cost)
            damping = torch.where(better, damping / 3.0, damping * 4.0).clamp(1e-12, 1e12)
            small = step.abs().amax(1) < tol
            active = active & ~(small | (damping >= 1e12))
            if not active.any():
                break
        return x.numpy().copy()
