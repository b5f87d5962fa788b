"""A particle in a latent space, integrated frame by frame (Bailey et al. 2016, §5.1).

The particle has unit mass, position ``x`` and velocity ``v`` in a model's latent space
and follows a path ``p(t)``, piecewise linear between frames. Per frame it is advanced
by one fourth-order Runge–Kutta step of ``h = 1/fps`` (the paper integrates frame by
frame so no step crosses a kink of the path). Forces:

- the **path constraint** ``‖x − p(t)‖² − r² ≤ 0`` (Eqs 9–10), by Baumgarte's
  stabilised Lagrange multiplier: ``F_c = λ g`` with ``g = x − p``,
  ``λ = −(gᵀF + G) / gᵀg`` and
  ``G = ‖ẋ − ṗ‖² + 2α gᵀ(ẋ − ṗ) + ½ β² (gᵀg − r²)``. The paper sets ``β = α²``;
  in this ``G`` that makes ``C̈ + 2αĊ + α⁴C = 0``, damping ratio ``1/α``: ringing for
  α > 1, and unstable under RK4 at 24 fps once ``α² h`` passes ~2.8. Ours: ``β = α``
  by default (Baumgarte's critically damped choice, ``(d/dt + α)² C = 0``), the
  paper's is ``baumgarte_beta=α**2``. *Erratum*: the paper prints
  ``λ = (−gᵀF + G)/gᵀg``; substituting ``ẍ = F + λg`` into ``C̈ + 2αĊ + β²C = 0``
  for ``C = gᵀg − r²`` (``p̈ = 0`` on a linear piece) gives ``−G``.
  The inequality: ``λ`` is set to 0 whenever it is positive, so ``F_c`` only
  ever pulls towards ``p``. Ours: it acts only in the outer shell
  ``‖g‖ ≥ 0.8 r``; deeper inside, ``1/gᵀg`` turns the ``‖ẋ − ṗ‖²`` term of a
  particle crossing near ``p`` (the start of every MOVE) into an unbounded pull;
- the **probability force** (Eqs 11–12): magnitude ``S = a (1 + exp((c − v)/l))⁻¹``
  along the unit gradient of ``c``. The paper's ``p(x|M)`` is taken here (ours) as the
  GP's normalised confidence ``c(x) = 1 − σ²(x)/σ²_rbf`` in [0, 1], from Eq 8's
  predictive variance (1 on the training points, 0 far from them);
- a **random force**, each component an independent zero-mean GP in time with
  ``k(t, t') = α_r exp(−(t − t')² / 2γ)``, drawn (ours) as a sum of random Fourier
  features (``M`` cosine/sine pairs at frequencies ``ω ~ N(0, 1/γ)``), so a seeded
  draw can be evaluated at any time, in any order, for any duration, with the
  kernel as its covariance in expectation over the frequencies;
- a viscous **drag** ``−c_d (ẋ − ṗ)`` (ours: the paper names no damping; without it
  the random force pumps energy into the particle for as long as it idles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rigmap.gp.distances import difference_squared_distances
from rigmap.gp.kernels import rbf, rbf_gram
from rigmap.gp.solve import add_noise, solve_lower, solve_lower_transposed
from rigmap.latent.errors import LatentInputError


@dataclass(frozen=True)
class ParticleSettings:
    """The simulation's parameters; latent lengths are in the model's latent units
    (latents start at unit scale, :class:`~rigmap.latent.GPLVM`). All values are ours
    unless said (the paper gives none)."""

    fps: float = 24.0  # the paper's
    radius: float = 0.12  # r
    alpha: float = 10.0  # Baumgarte α (1/s)
    baumgarte_beta: float | None = None  # β (1/s); None: β = α, critically damped
    drag: float = 3.0  # c_d (1/s)
    probability_force: float = 1.0  # a of Eq 11
    probability_threshold: float = 0.6  # v of Eq 11, on the confidence scale [0, 1]
    probability_width: float = 0.05  # l of Eq 11
    random_variance: float = 0.25  # α_r of the random force's kernel
    random_timescale_s: float = 0.4  # √γ of the random force's kernel
    random_features: int = 48  # M cosine/sine pairs per component
    shell: float = 0.8  # the constraint acts only where ‖x − p‖ ≥ shell · r

    def __post_init__(self) -> None:
        for name in ("fps", "radius", "alpha", "random_timescale_s", "probability_width"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise LatentInputError(f"particle setting {name} must be > 0, got {value!r}")
        for name in ("drag", "probability_force", "random_variance"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise LatentInputError(f"particle setting {name} must be ≥ 0, got {value!r}")
        if self.random_features < 1:
            raise LatentInputError(f"random_features must be ≥ 1, got {self.random_features}")

    @property
    def beta(self) -> float:
        return self.alpha if self.baumgarte_beta is None else self.baumgarte_beta


class LatentField:
    """One model's latent space as plain numpy for the per-frame work: the GP's
    confidence and its gradient (Eq 8's variance) and the controls at a point (Eq 8's
    mean → PCA back-projection → unscale → clamp, with ``K⁻¹Y`` and the PCA basis
    folded into one ``(N, C)`` matrix, so a pose costs one kernel row and one product,
    linear in the training size as §4.4 notes)."""

    def __init__(self, model):
        g = model.gplvm
        self.model = model
        self.X = np.asarray(g.X, dtype=np.float64)
        self.q = self.X.shape[1]
        self.variance = float(g.kernel_variance)
        self.lengthscale2 = float(g.lengthscale2)
        K = add_noise(rbf_gram(self.X, self.X, self.variance, self.lengthscale2), g.white_variance)
        # solves, not an inverse: K is ill-conditioned. numpy's Cholesky, not the core's
        # (SciPy's): they differ in the last bits, and the committed syntheses used this one
        self.L = np.linalg.cholesky(K)
        alpha = g._alpha.numpy()  # K⁻¹ Y (N, d)
        pca = model.pca
        self.B = alpha @ pca.components_  # (N, D): scaled controls per kernel weight
        self.z0 = np.asarray(pca.mean_, dtype=np.float64)
        s = model.scaling
        self.w = np.where(s.weights > 0, s.weights, 1.0)
        self.moving = s.weights > 0
        self.mean = s.mean
        self.lower, self.upper = s.lower, s.upper

    def kernel_row(self, x: np.ndarray) -> np.ndarray:
        return rbf(self._squared_distances(x), self.variance, self.lengthscale2)

    def _squared_distances(self, x: np.ndarray) -> np.ndarray:
        return difference_squared_distances(x[None], self.X)[0]

    def confidence(self, x: np.ndarray) -> float:
        v = solve_lower(self.L, self.kernel_row(x))
        return float(v @ v) / self.variance

    def confidence_and_gradient(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """``c(x) = kᵀK⁻¹k / σ²_rbf`` and ``∇c = −2/(σ²_rbf l²) Σ_i k_i u_i (x − x_i)``,
        ``u = K⁻¹k`` (two triangular solves, quadratic in the training size)."""
        k = self.kernel_row(x)
        v = solve_lower(self.L, k)
        u = solve_lower_transposed(self.L, v)
        c = float(v @ v) / self.variance
        grad = -2.0 / (self.variance * self.lengthscale2) * ((k * u) @ (x - self.X))
        return c, grad

    def controls(self, x: np.ndarray, *, clamp: bool = True) -> np.ndarray:
        """Used-control values ``(C,)`` at one latent point (the model's
        :meth:`~rigmap.latent.LatentModel.to_controls`, without its per-call overhead)."""
        z = self.z0 + self.kernel_row(x) @ self.B
        p = np.where(self.moving, (z - self.mean) / self.w + self.mean, self.mean)
        return np.clip(p, self.lower, self.upper) if clamp else p

    def nearest(self, x: np.ndarray) -> int:
        return int(self._squared_distances(x).argmin())


class RandomForce:
    """A seeded draw of a ``q``-component GP in time (kernel ``α_r exp(−Δt²/2γ)``) by
    random Fourier features: ``f(t) = √(α_r/M) Σ_m a_m cos(ω_m t) + b_m sin(ω_m t)``."""

    def __init__(self, q: int, settings: ParticleSettings, seed: int):
        rng = np.random.default_rng(seed)
        M = settings.random_features
        self.omega = rng.standard_normal((q, M)) / settings.random_timescale_s
        self.a = rng.standard_normal((q, M))
        self.b = rng.standard_normal((q, M))
        self.scale = math.sqrt(settings.random_variance / M)

    def __call__(self, t: float) -> np.ndarray:
        phase = self.omega * t
        return self.scale * (self.a * np.cos(phase) + self.b * np.sin(phase)).sum(1)


class Particle:
    """The particle in one latent field; :meth:`step` advances it by one frame."""

    def __init__(
        self,
        field: LatentField,
        x0,
        *,
        settings: ParticleSettings | None = None,
        seed: int = 0,
        t0: float = 0.0,
        v0=None,
    ):
        self.field = field
        self.settings = settings or ParticleSettings()
        self.x = np.array(x0, dtype=np.float64)
        if self.x.shape != (field.q,) or not np.isfinite(self.x).all():
            raise LatentInputError(
                f"particle start must be a finite point of shape ({field.q},), got {self.x}"
            )
        self.v = np.zeros(field.q) if v0 is None else np.array(v0, dtype=np.float64)
        self.t = float(t0)
        self.random = RandomForce(field.q, self.settings, seed)
        self.radius = self.settings.radius
        self.last_lambda = 0.0

    def free_force(self, t: float, x: np.ndarray, v: np.ndarray, pdot: np.ndarray) -> np.ndarray:
        """Every force but the constraint's: random + probability (Eqs 11–12) + drag."""
        s = self.settings
        force = self.random(t) - s.drag * (v - pdot)
        if s.probability_force > 0:
            c, grad = self.field.confidence_and_gradient(x)
            norm = float(np.sqrt(grad @ grad))
            if norm > 1e-12:
                z = (c - s.probability_threshold) / s.probability_width
                S = s.probability_force / (1.0 + math.exp(min(z, 700.0)))
                force = force + (S / norm) * grad
        return force

    def acceleration(self, t, x, v, p, pdot) -> np.ndarray:
        s = self.settings
        F = self.free_force(t, x, v, pdot)
        g = x - p
        gg = float(g @ g)
        if gg < (s.shell * self.radius) ** 2:  # deep inside: the wall is not touched
            self.last_lambda = 0.0
            return F
        dv = v - pdot
        G = float(dv @ dv) + 2.0 * s.alpha * float(g @ dv) + 0.5 * s.beta**2 * (gg - self.radius**2)
        lam = min(0.0, -(float(g @ F) + G) / gg)  # only ever towards p (the inequality)
        self.last_lambda = lam
        return F + lam * g

    def step(self, p0, p1) -> np.ndarray:
        """One frame along the path piece from ``p0`` (now) to ``p1`` (next frame), by RK4;
        returns the new position.

        A radius below the settings' is stiffer (the constraint's ``λ`` grows like
        ``1/r²``), so the frame is split into ``⌈r_settings / r⌉`` RK4 sub-steps (ours:
        this keeps ``h²λ`` where the default radius has it; without it a PLAY approach at
        a quarter of ``r`` diverged at 24 fps)."""
        frame = 1.0 / self.settings.fps
        p0 = np.asarray(p0, dtype=np.float64)
        pdot = (np.asarray(p1, dtype=np.float64) - p0) / frame
        substeps = max(1, math.ceil(self.settings.radius / self.radius - 1e-9))
        h = frame / substeps
        for k in range(substeps):
            start = p0 + k * h * pdot
            was_within = float(np.linalg.norm(self.x - start)) <= self.radius
            self._rk4(h, start, pdot)
            if was_within:
                self._keep_within(start + h * pdot, pdot)
        if not (np.isfinite(self.x).all() and np.isfinite(self.v).all()):
            raise FloatingPointError(f"the particle diverged at t = {self.t:.3f} s")
        return self.x

    def _keep_within(self, p: np.ndarray, pdot: np.ndarray) -> None:
        """Put a particle that was within ``r`` and stepped past it back on the sphere.

        Ours: post-stabilisation of the inequality. Baumgarte's term alone lets a particle
        that enters the shell fast overshoot (measured: 4.5 % of ``r`` in an IDLE, seed 2);
        the outward part of its velocity relative to the path is removed with it. A
        particle already outside (a shrinking PLAY radius) is left to the pull.
        """
        g = self.x - p
        distance = float(np.sqrt(g @ g))
        if distance <= self.radius:
            return
        u = g / distance
        self.x = p + self.radius * u
        outward = float((self.v - pdot) @ u)
        if outward > 0:
            self.v = self.v - outward * u

    def _rk4(self, h: float, p0: np.ndarray, pdot: np.ndarray) -> None:
        t0, x, v = self.t, self.x, self.v

        def deriv(dt, xs, vs):
            return vs, self.acceleration(t0 + dt, xs, vs, p0 + dt * pdot, pdot)

        k1x, k1v = deriv(0.0, x, v)
        k2x, k2v = deriv(0.5 * h, x + 0.5 * h * k1x, v + 0.5 * h * k1v)
        k3x, k3v = deriv(0.5 * h, x + 0.5 * h * k2x, v + 0.5 * h * k2v)
        k4x, k4v = deriv(h, x + h * k3x, v + h * k3v)
        self.x = x + (h / 6.0) * (k1x + 2 * k2x + 2 * k3x + k4x)
        self.v = v + (h / 6.0) * (k1v + 2 * k2v + 2 * k3v + k4v)
        self.t = t0 + h

    def place(self, x, v=None) -> None:
        """Put the particle at ``x`` (playing an embedded take moves it by hand)."""
        self.x = np.array(x, dtype=np.float64)
        self.v = np.zeros_like(self.x) if v is None else np.array(v, dtype=np.float64)
        self.t += 1.0 / self.settings.fps
