"""Refinement by damped least squares (paper §4.3, Eq. 13).

Starting from a regressor's guess ``y``, repeat ``Δx = x* − f(y)``,
``Δy = (JᵀJ + λ²I)⁻¹ Jᵀ Δx``, ``y ← y + Δy`` until ``Δx`` is small or an
iteration cap is reached. Only the used controls move (the Jacobian has
columns for them alone), so unused controls stay at their defaults.

Controls mix units — centimetres, radians, 0-1 switches — so the plain
``λ²‖Δy‖²`` penalty of Eq. 13 weighs a radian like a centimetre and lets
the step pour into whichever controls are cheapest in their own unit. On the
built-in rigs those are the FK rotations of limbs the animators keep in IK:
at a predicted IK/FK blend of 0.8-0.9 they still move the joints a little,
so plain Eq. 13 swings them by radians although the animators moved them by
thousandths of one (issue #7; paper Fig. 11, controls "drifting along
manifolds in the rig space"). With ``control_scale`` (the training-corpus
standard deviation of each control, the scale the ground-truth error uses)
the step is solved in normalised controls ``z = y / σ``: ``J_z = J·diag(σ)``,
``Δy = σ ⊙ Δz``, so λ prices one training std of any control alike and a
control the animators barely moved is stiff. ``keep_in_range`` projects
every iterate into the controls' soft ranges (widened to include the start),
so a 0-1 switch stays a switch.

The Jacobian comes from a *source*: computed on the rig at every iteration
(finite differences, valid for any black-box rig; or autodiff on a built-in
rig), or predicted once at the target by a learned model (§4.4) — the
paper's cheaper variant. Every rig evaluation is counted, because on a real
DCC rig they are what costs time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rigmap.refine.jacobian import jacobian
from rigmap.rigs.base import Rig, RigInputError, check_positions


class JacobianSource(Protocol):
    """Gives ``(N, 3J, C_used)`` Jacobians and says how many rig evaluations that cost."""

    #: True when the Jacobian depends on the current controls (recomputed each iteration)
    per_iteration: bool

    def __call__(self, Y_full: np.ndarray, X_target: np.ndarray) -> tuple[np.ndarray, int]: ...


@dataclass
class ComputedJacobian:
    """The rig's own Jacobian at the current controls (finite differences or autodiff)."""

    rig: Rig
    method: str = "finite_difference"
    per_iteration: bool = True

    def __call__(self, Y_full: np.ndarray, X_target: np.ndarray) -> tuple[np.ndarray, int]:
        J = jacobian(self.rig, Y_full, method=self.method)
        n_used = len(self.rig.controls.used_indices)
        # central differences: two evaluations per used control per frame; autodiff: one pass
        cost = len(Y_full) * (2 * n_used if self.method == "finite_difference" else 1)
        return J, cost


@dataclass
class PredictedJacobian:
    """A learned Jacobian predicted once at the target pose (Algorithm 1, line 9).

    ``model.predict(X_flat)`` must return ``(N, 3J, C_used)`` (or flattened).
    """

    model: object
    per_iteration: bool = False

    def __call__(self, Y_full: np.ndarray, X_target: np.ndarray) -> tuple[np.ndarray, int]:
        n = len(X_target)
        J = np.asarray(self.model.predict(X_target.reshape(n, -1)))
        return J.reshape(n, X_target[0].size, -1), 0


@dataclass
class RefineResult:
    """Refined used-control values and what it took to get them."""

    Y_used: np.ndarray  # (N, C_used), the best iterate per frame
    joint_error: np.ndarray  # (N,) mean squared joint error of the returned controls
    initial_joint_error: np.ndarray  # (N,)
    iterations: np.ndarray  # (N,) iterations each frame ran
    rig_evaluations: int  # poses evaluated, including finite-difference perturbations


def chiaverini_damping(
    singular_values: np.ndarray, epsilon: float, max_damping: float
) -> np.ndarray:
    """λ per frame from the smallest singular value (Chiaverini 1993, paper refs [12][23]).

    No damping while ``σ_min ≥ ε``; below it λ² grows smoothly to ``max_damping²``
    as ``σ_min → 0``, so steps stay bounded near singular poses. A rig with more
    controls than its joints can tell apart has ``σ_min = 0`` at every pose, and
    then this is simply ``λ = max_damping``.
    """
    smallest = singular_values[:, -1]
    ratio = np.clip(smallest / epsilon, 0.0, 1.0)
    return np.sqrt((1.0 - ratio**2) * max_damping**2)


def damped_least_squares(
    rig: Rig,
    Y_used: np.ndarray,
    X_target: np.ndarray,
    jacobian_source: JacobianSource,
    *,
    damping: float | str = 0.1,
    tolerance: float = 1e-3,
    max_iterations: int = 10,
    control_scale: np.ndarray | None = None,
    keep_in_range: bool = False,
    auto_epsilon: float = 1.0,
    auto_max_damping: float = 1.0,
) -> RefineResult:
    """Refine ``(N, C_used)`` controls so the rig reproduces ``X_target`` (COG-relative).

    ``damping`` is λ or ``"auto"`` (Chiaverini's rule with ``auto_epsilon`` and
    ``auto_max_damping``). Without ``control_scale`` λ is in rig length units
    per control unit, the literal Eq. 13. ``control_scale`` ``(C_used,)`` —
    normally each control's training-corpus standard deviation
    (``rigmap.evaluation.metrics.control_std``) — solves the step in
    ``y / control_scale`` instead, so λ is in rig length units per training
    std; a control with scale 0 (never moved in training) does not move.
    ``keep_in_range`` keeps every control inside its soft range
    ``[lower, upper]`` (or where it started, if the guess was already outside).
    A frame stops when its mean squared joint error is below ``tolerance``
    (units²). The best iterate seen per frame is returned, so a diverging step
    never makes a frame worse.
    """
    X_target = check_positions(X_target, rig.n_joints, f"refine target for rig {rig.name!r}")
    Y_used = np.asarray(Y_used, dtype=np.float64)
    n_used = len(rig.controls.used_indices)
    if Y_used.shape != (len(X_target), n_used):
        raise RigInputError(
            f"refine on rig {rig.name!r}: expected initial controls of shape "
            f"({len(X_target)}, {n_used}) (used controls), got {Y_used.shape}"
        )
    if not np.isfinite(Y_used).all():
        raise RigInputError(f"refine on rig {rig.name!r}: initial controls contain NaN or inf")
    if damping != "auto" and not (isinstance(damping, int | float) and damping >= 0):
        raise ValueError(f"damping must be a non-negative number or 'auto', got {damping!r}")
    if max_iterations < 0:
        raise ValueError(f"max_iterations must be >= 0, got {max_iterations}")
    scale = _checked_scale(rig, control_scale, n_used)
    if keep_in_range:
        used = rig.controls.used_indices
        lower = np.minimum(rig.controls.lower[used], Y_used)
        upper = np.maximum(rig.controls.upper[used], Y_used)

    n = len(X_target)
    target = X_target.reshape(n, -1)
    y = Y_used.copy()
    evaluations = 0

    def error_of(controls: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        nonlocal evaluations
        x = rig.evaluate(rig.expand_used(controls)).reshape(len(frames), -1)
        evaluations += len(frames)
        residual = target[frames] - x
        return residual, (residual**2).mean(axis=1)

    all_frames = np.arange(n)
    residual, error = error_of(y, all_frames)
    initial = error.copy()
    best_y, best_error = y.copy(), error.copy()
    iterations = np.zeros(n, dtype=np.int64)
    cached_J = None
    active = error >= tolerance
    for _ in range(max_iterations):
        frames = np.flatnonzero(active)
        if frames.size == 0:
            break
        if jacobian_source.per_iteration or cached_J is None:
            J, cost = jacobian_source(rig.expand_used(y[frames]), X_target[frames])
            evaluations += cost
            if not jacobian_source.per_iteration:
                cached_J = np.empty((n, *J.shape[1:]))
                cached_J[frames] = J
        if cached_J is not None:
            J = cached_J[frames]
        J_scaled = J if scale is None else J * scale  # ∂x/∂z with y = scale · z
        U, s, Vt = np.linalg.svd(J_scaled, full_matrices=False)
        lam = (
            chiaverini_damping(s, auto_epsilon, auto_max_damping)
            if damping == "auto"
            else np.full(len(frames), float(damping))
        )
        gain = s / (s**2 + lam[:, None] ** 2)  # (F, k): the damped pseudo-inverse's spectrum
        projected = np.einsum("fjk,fj->fk", U, residual[frames])
        step = np.einsum("fkc,fk->fc", Vt, gain * projected)
        y[frames] += step if scale is None else step * scale
        if keep_in_range:
            y[frames] = np.clip(y[frames], lower[frames], upper[frames])
        iterations[frames] += 1
        new_residual, new_error = error_of(y[frames], frames)
        residual[frames], error[frames] = new_residual, new_error
        better = new_error < best_error[frames]
        best_y[frames[better]] = y[frames[better]]
        best_error[frames[better]] = new_error[better]
        active[frames] = new_error >= tolerance
    return RefineResult(best_y, best_error, initial, iterations, evaluations)


def _checked_scale(rig: Rig, control_scale, n_used: int) -> np.ndarray | None:
    if control_scale is None:
        return None
    scale = np.asarray(control_scale, dtype=np.float64)
    if scale.shape != (n_used,) or not np.isfinite(scale).all() or (scale < 0).any():
        shown = f"shape {scale.shape}"
        if scale.size and np.isfinite(scale).any():
            shown += f", minimum {np.nanmin(scale):g}"
        raise RigInputError(
            f"refine on rig {rig.name!r}: expected control_scale of shape ({n_used},) "
            f"(one finite value >= 0 per used control, e.g. its training std), got {shown}"
        )
    return scale
