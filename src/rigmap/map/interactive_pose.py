"""Posing while an animator drags effectors: one pose per call, at interactive rates (Fig. 5).

:func:`rigmap.map.effectors.pose_from_effectors` refines a batch of poses from their
guesses with central differences at every iteration: right for a file of targets, but a
few poses per second when called once per pose. A drag is a *stream* of nearby targets,
and :class:`InteractivePoser` makes each of its poses cost four small rig calls, on one
thread (on two cores, threads of so small a call only wait for each other):

1. the partial mapping's guess, and the last pose moved as the guess moved (a drag moves
   the targets a little, so that start is usually the closer one): both in one call;
2. the last pose's Jacobian (Broyden-updated), recomputed by forward differences at the
   better start only on the first pose or when a step with it does not bring the effectors
   closer (``carry_jacobian``; off: a fresh one for every pose). Only the controls that can
   move the effectors are differenced (:func:`moving_controls`: 82 of the biped's 211);
3. ``steps`` damped least-squares steps (Eq. 13 in training-std units, controls kept in
   their soft ranges), each tried at the lengths ``STEP_LENGTHS`` in one call (a line
   search at no extra call), the Jacobian corrected after each by Broyden's rank-one
   update along the step taken.

The rig calls go through the built-in rig's TorchScript traces
(:meth:`rigmap.rigs.engine.torch_rig.TorchRig.traced_pose`), which halve the cost of a
small batch; a DCC rig is called as it is. ``benchmarks/map.py`` measures the rate and the
distance reached beside the batch refinement.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.map.clip import held_controls
from rigmap.map.partial import SubsetMapping
from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.refine.jacobian import jacobian
from rigmap.refine.jacobian_reuse import broyden_update
from rigmap.refine.normal_equations import Damping
from rigmap.refine.solvers import damped_solver
from rigmap.rigs.base import RigInputError
from rigmap.torch_threads import one_thread

#: the damped step is tried at these fractions of its length, in one rig call (ours)
STEP_LENGTHS = np.array([1.0, 0.5, 0.25])


@dataclass
class PoseResult:
    """One pose: the full control row, its RMS distance to the targets (cm), its cost, and
    every joint's world position (cm; from the evaluation that chose it: a page showing the
    pose needs no other rig call)."""

    controls: np.ndarray  # (C,)
    distance_cm: float
    rig_evaluations: int
    joints: np.ndarray | None = None  # (J, 3)


class InteractivePoser:
    """``poser(targets (K, 3)) -> PoseResult`` for a stream of effector targets.

    ``damping`` is λ (cm per training std) or ``"auto"`` (Chiaverini's rule); ``steps``
    (default 2, ours) is the damped steps per pose; ``carry_jacobian`` (default on, ours)
    keeps the Jacobian from pose to pose (step 2 above); ``hold`` globs name used controls
    kept at ``hold_values`` (IK/FK switches), as in :class:`rigmap.map.clip.MapSettings`.
    :meth:`reset` starts a new drag (the next pose starts from its guess alone).
    """

    def __init__(
        self,
        rig,
        mapping: SubsetMapping,
        *,
        control_std: np.ndarray,
        hold_values: np.ndarray,
        hold=("*.ik_fk", "*.follow"),
        damping: float | str = "auto",
        steps: int = 2,
        carry_jacobian: bool = True,
    ):
        if not (isinstance(steps, int) and steps >= 1):
            raise ValueError(f"interactive posing: steps must be an integer >= 1, got {steps!r}")
        if not isinstance(carry_jacobian, bool):
            raise ValueError(
                f"interactive posing: carry_jacobian must be true or false, got {carry_jacobian!r}"
            )
        self.rig, self.mapping, self.steps = rig, mapping, steps
        self.view = WorldSubsetRig(rig, mapping.subset.joints, traced=True, keep_world=True)
        self.held = held_controls(rig, hold)
        self.hold_values = np.asarray(hold_values, dtype=np.float64)
        self.scale = np.asarray(control_std, dtype=np.float64).copy()
        self.scale[self.held] = 0.0  # a control with scale 0 does not move
        used = rig.controls.used_indices
        self.lower, self.upper = rig.controls.lower[used], rig.controls.upper[used]
        self.damping = Damping(None) if damping == "auto" else Damping(float(damping))
        self.columns = moving_controls(self.view, np.flatnonzero(self.scale > 0))
        self.last: tuple[np.ndarray, np.ndarray] | None = None  # (last pose, its guess)
        self.carry = carry_jacobian
        self.J: np.ndarray | None = None  # (3K, U) the last pose's Jacobian, Broyden-updated

    def reset(self) -> None:
        """Forget the last pose and its Jacobian: a new drag."""
        self.last, self.J = None, None

    def __call__(self, targets) -> PoseResult:
        targets = np.asarray(targets, dtype=np.float64)
        k = len(self.mapping.subset.joints)
        if targets.shape != (k, 3) or not np.isfinite(targets).all():
            raise RigInputError(
                f"interactive posing on {self.rig.name!r}: expected finite targets of shape "
                f"({k}, 3) for {list(self.mapping.subset.joints)}, got {targets.shape}"
            )
        with one_thread():  # a pose is a few small calls: threads only contend
            return self._pose(targets, k)

    def _pose(self, targets: np.ndarray, k: int) -> PoseResult:
        goal = targets.reshape(-1)
        guess = self.mapping.predict(targets[None])[0]
        guess[self.held] = self.hold_values[self.held]
        lower, upper = np.minimum(self.lower, guess), np.maximum(self.upper, guess)
        starts = [guess] if self.last is None else [guess, self.last[0] + guess - self.last[1]]
        y, x, error, joints = self._best(np.clip(np.array(starts), lower, upper), goal)
        evaluations = len(starts)
        fresh = self.J is None or not self.carry
        if fresh:
            evaluations += self._recompute(y)
        for _ in range(self.steps):
            y_new, x_new, new_error, new_joints = self._step(y, x, goal, lower, upper)
            evaluations += len(STEP_LENGTHS)
            if new_error >= error and not fresh:  # the carried Jacobian no longer fits
                evaluations += self._recompute(y)
                fresh = True
                y_new, x_new, new_error, new_joints = self._step(y, x, goal, lower, upper)
                evaluations += len(STEP_LENGTHS)
            if new_error >= error:
                break
            y, x, error, joints = y_new, x_new, new_error, new_joints
        self.last = (y, guess)
        distance = np.sqrt(np.mean(((goal - x).reshape(k, 3) ** 2).sum(axis=1)))
        full = self.rig.expand_used(y[None])[0]
        return PoseResult(full, float(distance), evaluations, joints)

    def _recompute(self, y: np.ndarray) -> int:
        """A forward-difference Jacobian at ``y``; returns the rig evaluations it cost."""
        full = self.rig.expand_used(y[None])
        self.J = jacobian(self.view, full, differences="forward", chunk=None, columns=self.columns)[
            0
        ]
        return len(self.columns) + 1

    def _step(self, y, x, goal, lower, upper):
        """One damped step from ``y`` (whose effectors are at ``x``), tried at every length
        of ``STEP_LENGTHS`` in one rig call (a line search at no extra call); the Jacobian is
        then corrected by Broyden's update along the best trial. Returns that trial's
        controls, flat positions and mean squared error."""
        solver = damped_solver((self.J * self.scale)[None], self.damping)
        step = solver.solve((goal - x)[None])[0] * self.scale
        trials = np.clip(y + STEP_LENGTHS[:, None] * step, lower, upper)
        y_new, x_new, new_error, joints = self._best(trials, goal)
        self.J = broyden_update(self.J[None], (y_new - y)[None], (x_new - x)[None])[0]
        return y_new, x_new, new_error, joints

    def _best(self, candidates: np.ndarray, goal: np.ndarray):
        """The candidate rows ``(P, U)`` closest to ``goal``, evaluated in one rig call:
        its controls, flat subset positions, mean squared error and every joint's world
        position (None for a rig the view cannot see whole)."""
        x = np.asarray(self.view.evaluate(self.rig.expand_used(candidates)))
        x = x.reshape(len(candidates), -1)
        errors = np.mean((goal - x) ** 2, axis=1)
        best = int(np.argmin(errors))
        world = self.view.last_world
        joints = None if world is None or len(world) != len(candidates) else world[best].copy()
        return candidates[best], x[best], float(errors[best]), joints


#: random poses on which :func:`moving_controls` looks for the controls that move a subset
PROBE_POSES = 16


def moving_controls(view: WorldSubsetRig, candidates: np.ndarray, seed: int = 0) -> np.ndarray:
    """The ``candidates`` (positions among the used controls) that move ``view``'s joints.

    Most of a body's controls cannot move a few effectors (fingers, eyes, a hand's own
    rotation at the wrist, an IK pole: on the biped 82 of its 211 used controls move the
    seven effectors), and a control whose Jacobian column is zero takes no step, so
    differencing it is wasted. Found once from central differences on ``PROBE_POSES``
    poses drawn uniformly over the soft ranges (ours), where every switch is partly on:
    a column zero on all of them is zero everywhere for any rig whose switches blend.
    """
    rig = view.inner
    used = rig.controls.used_indices
    rng = np.random.default_rng(seed)
    Y = np.repeat(rig.controls.defaults[None], PROBE_POSES, axis=0)
    Y[:, used] = rng.uniform(
        rig.controls.lower[used], rig.controls.upper[used], (PROBE_POSES, len(used))
    )
    J = jacobian(view, Y, differences="central", chunk=None, columns=candidates)
    return candidates[np.abs(J[:, :, candidates]).max(axis=(0, 1)) > 0]
