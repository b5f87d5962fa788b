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
paper's cheaper variant (``rigmap.refine.sources``). Every rig evaluation
is counted, because on a real DCC rig they are what costs time.

All frames of a clip are refined as one batch: residuals, Jacobians and
steps for every frame still moving go through the rig and the solver
together, and each frame leaves the batch when it reaches the tolerance.
The step is solved by normal equations and a batched Cholesky factorisation
(``solver="cholesky"``, ``rigmap.refine.normal_equations``), or on the
compact Jacobian's per-limb blocks (``solver="block_cholesky"``,
``rigmap.refine.block_cholesky``) — factorised once per frame for a learned
Jacobian, which stays fixed — or by each frame's SVD
(``solver="svd"``, exact λ, the original implementation). A computed Jacobian
can be reused across frames and iterations (``rigmap.refine.jacobian_reuse``).
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass

import numpy as np

from rigmap.refine.jacobian_reuse import JacobianReuse, anchor_frames, broyden_update
from rigmap.refine.normal_equations import SOLVERS, Damping
from rigmap.refine.solvers import damped_solver
from rigmap.refine.sources import JacobianSource
from rigmap.rigs.base import Rig, RigInputError, check_positions
from rigmap.torch_threads import blas_threads, torch_threads

#: with ``jacobian_update: carry``, a step that achieves less than this fraction of the
#: decrease its Jacobian predicted gets the frame a fresh Jacobian (ours: on the wolf's test
#: clips 0, 0.25, 0.5 and 0.75 ended at 0.36, 0.13, 0.072 and 0.066 cm² for 22, 23, 28 and
#: 35 rig evaluations per frame; 0 recomputes only when the error stopped falling)
CARRY_RECOMPUTE_RATIO = 0.75


@dataclass
class RefineResult:
    """Refined used-control values and what it took to get them."""

    Y_used: np.ndarray  # (N, C_used), the best iterate per frame
    joint_error: np.ndarray  # (N,) mean squared joint error of the returned controls
    initial_joint_error: np.ndarray  # (N,)
    iterations: np.ndarray  # (N,) iterations each frame ran
    rig_evaluations: int  # poses evaluated, including finite-difference perturbations


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
    solver: str = "cholesky",
    reuse: JacobianReuse | None = None,
    threads: int | None = 1,
    traced: bool = False,
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
    never makes a frame worse. ``solver`` is ``"cholesky"``, ``"block_cholesky"`` or ``"svd"``;
    ``reuse`` says how a computed Jacobian is reused (default: recomputed for
    every frame at every iteration). ``threads`` torch and numpy BLAS threads run the
    whole refinement, rig evaluations and a learned Jacobian's prediction included
    (``None``: the libraries' own): on this shared 2-core machine one thread evaluated
    the quadruped's batches 5-20x and predicted a clip's learned Jacobians 2.5-3x faster
    than two under load (``rigmap.torch_threads``; ours). ``traced`` evaluates a
    built-in rig's numpy batches by its TorchScript traces (``TorchRig.replaying_traces``:
    about twice as fast, the same positions); a rig without traces (Blender's) ignores it.
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
    if len(X_target) == 0:
        raise RigInputError(f"refine on rig {rig.name!r}: no frames to refine (an empty batch)")
    if not (isinstance(tolerance, int | float) and np.isfinite(tolerance) and tolerance >= 0):
        raise RigInputError(
            f"refine tolerance must be a finite number >= 0 (units²), got {tolerance!r}"
        )
    if solver not in SOLVERS:
        raise ValueError(f"refine solver: expected one of {SOLVERS}, got {solver!r}")
    lam = (
        Damping(None, auto_epsilon, auto_max_damping)
        if damping == "auto"
        else Damping(float(damping))
    )
    refinement = _Refinement(
        rig, Y_used, X_target, jacobian_source, lam, solver, reuse or JacobianReuse()
    )
    refinement.scale = _checked_scale(rig, control_scale, n_used)
    if keep_in_range:
        used = rig.controls.used_indices
        refinement.bounds = (
            np.minimum(rig.controls.lower[used], Y_used),
            np.maximum(rig.controls.upper[used], Y_used),
        )
    with torch_threads(threads), blas_threads(threads), _replaying_traces(rig, traced):
        return refinement.run(tolerance, max_iterations)


class _Refinement:
    """The state of one batch: controls, residuals, Jacobians, solvers, the evaluation count."""

    def __init__(self, rig, Y_used, X_target, source, damping, solver, reuse):
        self.rig, self.source, self.damping, self.solver, self.reuse = (
            rig,
            source,
            damping,
            solver,
            reuse,
        )
        self.X_target = X_target
        self.n = len(X_target)
        self.target = X_target.reshape(self.n, -1)
        self.y = Y_used.copy()
        self.x = np.zeros_like(self.target)  # the rig's positions at self.y (from error_of)
        self.evaluations = 0
        self.scale: np.ndarray | None = None
        self.bounds: tuple[np.ndarray, np.ndarray] | None = None
        self.J: np.ndarray | None = None  # (N, R, C) current Jacobians (reused sources)
        self.has_jacobian = np.zeros(self.n, dtype=bool)
        self.stalled = np.zeros(self.n, dtype=bool)
        self.fixed_solver = None  # a fixed source's factorised solver, built once
        self.solver_row = np.full(self.n, -1)

    def error_of(self, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = self.rig.evaluate(self.rig.expand_used(self.y[frames])).reshape(len(frames), -1)
        self.evaluations += len(frames)
        self.x[frames] = x
        residual = self.target[frames] - x
        return residual, (residual**2).mean(axis=1)

    def compute(self, frames: np.ndarray) -> np.ndarray:
        # the positions at y are known (the residual's evaluation): forward differences reuse them
        Y_full = self.rig.expand_used(self.y[frames])
        J, cost = self.source(Y_full, self.X_target[frames], frames, base=self.x[frames])
        self.evaluations += cost
        return np.asarray(J, dtype=np.float64)

    def step(self, frames: np.ndarray, residual: np.ndarray) -> np.ndarray:
        """Δy for ``frames`` (in the controls' units) from their residuals."""
        if not self.source.per_iteration:
            if self.fixed_solver is None:
                J = self.compute(frames)
                self.fixed_solver = damped_solver(J, self.damping, self.solver, self.scale)
                self.solver_row[frames] = np.arange(len(frames))
            dz = self.fixed_solver.solve(residual, self.solver_row[frames])
        else:
            if self.reuse.recomputes_every_iteration:
                J = self.compute(frames)
            else:
                J = self.reused_jacobians(frames)
            dz = damped_solver(J, self.damping, self.solver, self.scale).solve(residual)
        return dz if self.scale is None else dz * self.scale

    def reused_jacobians(self, frames: np.ndarray) -> np.ndarray:
        if self.J is None:
            self.J = np.zeros((self.n, self.target.shape[1], self.y.shape[1]))
        if self.reuse.update == "recompute":
            self.has_jacobian[frames] = False
        new = frames[~self.has_jacobian[frames]]
        if new.size:
            anchors, nearest = anchor_frames(new, self.reuse.share_every)
            self.J[new] = self.compute(anchors)[nearest]
        if self.reuse.recompute_on_stall:
            own = frames[self.has_jacobian[frames] & self.stalled[frames]]
            if own.size:
                self.J[own] = self.compute(own)
        self.has_jacobian[frames] = True
        return self.J[frames]

    def run(self, tolerance: float, max_iterations: int) -> RefineResult:
        if self.source.per_iteration and self.reuse.update == "carry":
            return self.run_in_order(tolerance, max_iterations)
        all_frames = np.arange(self.n)
        residual, error = self.error_of(all_frames)
        initial = error.copy()
        best_y, best_error = self.y.copy(), error.copy()
        iterations = np.zeros(self.n, dtype=np.int64)
        active = error >= tolerance
        broyden = self.source.per_iteration and self.reuse.update == "broyden"
        for _ in range(max_iterations):
            frames = np.flatnonzero(active)
            if frames.size == 0:
                break
            before = self.y[frames].copy()
            self.y[frames] += self.step(frames, residual[frames])
            if self.bounds is not None:
                self.y[frames] = np.clip(
                    self.y[frames], self.bounds[0][frames], self.bounds[1][frames]
                )
            iterations[frames] += 1
            new_residual, new_error = self.error_of(frames)
            if broyden:  # Δx = f(y_new) − f(y_old) = r_old − r_new
                dx = residual[frames] - new_residual
                self.J[frames] = broyden_update(self.J[frames], self.y[frames] - before, dx)
            self.stalled[frames] = new_error >= error[frames]
            residual[frames], error[frames] = new_residual, new_error
            better = new_error < best_error[frames]
            best_y[frames[better]] = self.y[frames[better]]
            best_error[frames[better]] = new_error[better]
            active[frames] = new_error >= tolerance
        return RefineResult(best_y, best_error, initial, iterations, self.evaluations)

    def run_in_order(self, tolerance: float, max_iterations: int) -> RefineResult:
        """The batch's frames one after another (``reuse.update == "carry"``): the batch must
        be one clip's consecutive frames, as the evaluation gives it.

        Motion is continuous, so the previous frame's final Jacobian (Broyden-updated along
        its steps) is a good start for the next, and its refined pose, moved as the guess
        moved, a start often closer than the guess: both starts are evaluated in one rig call
        and the closer kept (as interactive posing does, ``rigmap.map.interactive_pose``).
        A frame's Jacobian is computed afresh (once per frame, at most) when a step lowered
        the error by less than ``CARRY_RECOMPUTE_RATIO`` of what the Jacobian predicted, a
        failed step included, and another step follows: full Jacobians are paid only where
        the carried one stopped fitting. Every step counts as an iteration.
        """
        guess = self.y.copy()
        best_error, initial = np.empty(self.n), np.empty(self.n)
        iterations = np.zeros(self.n, dtype=np.int64)
        self.J = np.zeros((self.n, self.target.shape[1], self.y.shape[1]))
        for t in range(self.n):
            starts = guess[t : t + 1]
            if t:  # the last refined pose moved as the guess moved (a second start)
                starts = np.concatenate([starts, self.y[t - 1 : t] + guess[t] - guess[t - 1]])
            errors = self.try_poses(t, starts)
            initial[t], best_error[t] = errors[0], errors.min()
            fresh = t == 0
            self.J[t] = self.compute(np.array([t]))[0] if fresh else self.J[t - 1]
            for k in range(max_iterations):
                if best_error[t] < tolerance:
                    break
                before = best_error[t]
                error, predicted = self.carried_step(t)
                iterations[t] += 1
                best_error[t] = min(before, error)
                fitted = before - error >= CARRY_RECOMPUTE_RATIO * (before - predicted)
                if not (fresh or fitted) and k + 1 < max_iterations:
                    self.J[t], fresh = self.compute(np.array([t]))[0], True
        return RefineResult(self.y, best_error, initial, iterations, self.evaluations)

    def try_poses(self, t: int, Y: np.ndarray) -> np.ndarray:
        """Frame ``t``'s candidate controls ``Y`` (rows) in one rig call; the closest becomes
        its iterate (``self.y[t]``, ``self.x[t]``). Returns every row's mean squared error."""
        if self.bounds is not None:
            Y = np.clip(Y, self.bounds[0][t], self.bounds[1][t])
        x = self.rig.evaluate(self.rig.expand_used(Y)).reshape(len(Y), -1)
        self.evaluations += len(Y)
        errors = ((self.target[t] - x) ** 2).mean(axis=1)
        best = int(np.argmin(errors))
        self.y[t], self.x[t] = Y[best], x[best]
        return errors

    def carried_step(self, t: int) -> tuple[float, float]:
        """One damped step of frame ``t`` with its current Jacobian, which Broyden's update
        then corrects along the step; the frame moves only if its error fell. Returns the
        error at the step's end and the error the Jacobian predicted there."""
        y, x = self.y[t], self.x[t]
        residual = self.target[t] - x
        solver = damped_solver(self.J[t : t + 1], self.damping, self.solver, self.scale)
        dz = solver.solve(residual[None])[0]
        y_new = y + (dz if self.scale is None else dz * self.scale)
        if self.bounds is not None:
            y_new = np.clip(y_new, self.bounds[0][t], self.bounds[1][t])
        predicted = float(((residual - self.J[t] @ (y_new - y)) ** 2).mean())
        x_new = self.rig.evaluate(self.rig.expand_used(y_new[None])).reshape(-1)
        self.evaluations += 1
        dx = (x_new - x)[None]  # f(y_new) − f(y)
        self.J[t] = broyden_update(self.J[t : t + 1], (y_new - y)[None], dx)[0]
        error = float(((self.target[t] - x_new) ** 2).mean())
        if error < float((residual**2).mean()):
            self.y[t], self.x[t] = y_new, x_new
        return error, predicted


def _replaying_traces(rig, traced: bool):
    """The rig's ``replaying_traces()`` (looked up through wrappers), or a no-op."""
    inner = rig
    while not hasattr(inner, "replaying_traces") and hasattr(inner, "wrapped"):
        inner = inner.wrapped
    if traced and hasattr(inner, "replaying_traces"):
        return inner.replaying_traces()
    return nullcontext()


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
