"""The damped step of Eq. 13 for a batch of frames: SVD (exact) or normal equations + Cholesky.

``Δz = (JᵀJ + λ²I)⁻¹ Jᵀ r`` for every frame at once. The SVD form is what
rigmap did first: it gives every singular value, so Chiaverini's λ is exact,
but a 228 × 218 SVD costs about 8 ms per frame. Forming ``JᵀJ`` and a batched
Cholesky factorisation in float64 costs about 1 ms, λ then comes from an
inverse-iteration estimate of ``σ_min`` on the same factor
(``rigmap.refine.damping``) — or exactly 0 when a control moves no joint —
and a factor is reused as long as the Jacobian
stays the same — a learned Jacobian predicted once at the target is
factorised once per frame, and every further iteration is two triangular
solves.

When λ differs from the shift the factor was built with (``ε²`` for the
σ estimate), the system ``(M − δI) x = b`` is solved on ``M``'s factor by the
fixed-point iteration ``x ← M⁻¹(b + δx)``, which contracts by
``|δ| / (σ_min² + ε²)``; frames where that is not small get a factor of their
own. A frame whose matrix is singular (λ = 0 on a rank-deficient Jacobian)
falls back to the SVD pseudo-inverse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from rigmap.refine.damping import chiaverini_damping, smallest_singular_value
from rigmap.torch_threads import one_thread

SOLVERS = ("cholesky", "block_cholesky", "svd")

#: fixed-point solves are used while they contract at least this fast (ours)
REUSE_CONTRACTION = 0.05
FIXED_POINT_STEPS = 60
FIXED_POINT_TOLERANCE = 1e-10  # far below the λ estimate's own ~1e-3


@dataclass(frozen=True)
class Damping:
    """λ: a number (cm per control unit or per training std), or Chiaverini's rule."""

    value: float | None = None  # None: automatic
    epsilon: float = 1.0
    max_damping: float = 1.0

    @property
    def automatic(self) -> bool:
        return self.value is None


class SVDStep:
    """Eq. 13 from each frame's SVD (exact σ_min for the automatic λ)."""

    def __init__(self, J: np.ndarray, damping: Damping):
        self.U, s, self.Vt = np.linalg.svd(J, full_matrices=False)
        if damping.automatic:
            self.damping = chiaverini_damping(s, damping.epsilon, damping.max_damping)
        else:
            self.damping = np.full(len(J), float(damping.value))
        denominator = s**2 + self.damping[:, None] ** 2
        # the damped pseudo-inverse's spectrum (a zero singular value undamped gets no step)
        self.gain = np.divide(s, denominator, out=np.zeros_like(s), where=denominator > 0)

    def solve(self, residual: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Steps for ``residual`` ``(F', R)``, of the solver's frames ``rows`` (default all)."""
        U, Vt, gain = (
            (self.U, self.Vt, self.gain)
            if rows is None
            else (self.U[rows], self.Vt[rows], self.gain[rows])
        )
        projected = np.einsum("fjk,fj->fk", U, residual)
        return np.einsum("fkc,fk->fc", Vt, gain * projected)


class CholeskyStep:
    """Eq. 13 by normal equations, factorised once in float64 and reused for every solve."""

    def __init__(self, J: np.ndarray, damping: Damping):
        with one_thread():
            self._factorise(J, damping)

    def _factorise(self, J: np.ndarray, damping: Damping) -> None:
        self.J = torch.as_tensor(np.asarray(J, dtype=np.float64))
        n_frames, _, n_columns = self.J.shape
        normal = torch.bmm(self.J.transpose(1, 2), self.J)
        eye = torch.eye(n_columns, dtype=torch.float64)
        if damping.automatic:
            shift = float(damping.epsilon) ** 2
            factor, _ = torch.linalg.cholesky_ex(normal + shift * eye)  # PD: shift > 0
            sigma = np.zeros(n_frames)
            estimated = np.flatnonzero(~_surely_singular(self.J))
            if estimated.size:
                index = torch.as_tensor(estimated)
                sigma[estimated] = smallest_singular_value(self.J[index], factor[index]).numpy()
            lam = chiaverini_damping(sigma, damping.epsilon, damping.max_damping)
            deficit = shift - lam**2
            contraction = np.abs(deficit) / (sigma**2 + shift)
            own = np.flatnonzero(contraction > REUSE_CONTRACTION)
            deficit[own] = 0.0
        else:
            lam = np.full(n_frames, float(damping.value))
            factor, deficit, own = None, np.zeros(n_frames), np.arange(n_frames)
        self.damping = lam
        self.deficit = torch.as_tensor(deficit)[:, None, None]
        self.singular = np.zeros(n_frames, dtype=bool)
        if own.size:
            shifts = torch.as_tensor(lam[own] ** 2)[:, None, None]
            own_factor, info = torch.linalg.cholesky_ex(normal[own] + shifts * eye)
            factor = (
                own_factor
                if factor is None
                else factor.index_copy(0, torch.as_tensor(own), own_factor)
            )
            self.singular[own[info.numpy() > 0]] = True
        self.factor = factor

    def solve(self, residual: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Steps for ``residual`` ``(F', R)``, of the solver's frames ``rows`` (default all)."""
        with one_thread():
            return self._solve(residual, np.arange(len(self.J)) if rows is None else rows)

    def _solve(self, residual: np.ndarray, rows: np.ndarray) -> np.ndarray:
        rows = np.asarray(rows)
        index = torch.as_tensor(rows)
        J, factor, deficit = self.J[index], self.factor[index], self.deficit[index]
        rhs = torch.bmm(J.transpose(1, 2), torch.as_tensor(residual)[:, :, None])
        step = _cholesky_solve(rhs, factor)
        if bool((deficit != 0).any()):
            for _ in range(FIXED_POINT_STEPS):
                new = _cholesky_solve(rhs + deficit * step, factor)
                change = torch.linalg.vector_norm(new - step) / torch.linalg.vector_norm(new)
                step = new
                if float(change) < FIXED_POINT_TOLERANCE:
                    break
        out = step[:, :, 0].numpy()
        singular = self.singular[rows]
        if singular.any():
            fallback = SVDStep(self.J[index[torch.as_tensor(singular)]].numpy(), Damping(0.0))
            out[singular] = fallback.solve(residual[singular])
        return out


def _cholesky_solve(rhs: torch.Tensor, factor: torch.Tensor) -> torch.Tensor:
    """``(LLᵀ)⁻¹ rhs`` by two batched triangular solves (faster than ``cholesky_solve`` here)."""
    half = torch.linalg.solve_triangular(factor, rhs, upper=False)
    return torch.linalg.solve_triangular(factor.transpose(1, 2), half, upper=True)


def _surely_singular(J: torch.Tensor) -> np.ndarray:
    """Frames whose ``σ_min`` is exactly 0: a control that moves no joint, or fewer rows.

    On the built-in rigs every computed Jacobian has such columns (controls
    of limbs held in the other IK/FK mode, switches at their ends), so their
    automatic λ is exact without any estimate.
    """
    if J.shape[1] < J.shape[2]:
        return np.ones(len(J), dtype=bool)
    return (J.abs().amax(dim=1) == 0).any(dim=1).numpy()
