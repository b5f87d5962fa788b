"""Refinement that stays near the mapping's guess: damped least squares with a prior term.

Mapped targets (mocap, effectors) drive a few joints, and many used controls barely move
them: the roll of a hand about the wrist → knuckle axis, a foot's bank, how the body's
travel is split between the root and the COG. Eq. 13 refines each frame on its own, so
over a few iterations those poorly determined controls wander along the rig's null
directions (paper §7.1 "Rig function ambiguity", Fig. 11) — a little differently on every
frame. Measured on the CMU walk → biped (30 fps): the guess's largest frame-to-frame jump
of a used control is 2.1 training std, after three plain iterations 7.7 std (root.tz and
cog.tz swinging ±45 cm against each other through a fast kick), and the noisy curves then
need keys on half the frames.

The fix is Tikhonov regularisation toward the guess ``g`` (smooth over time, because the
regressor is a smooth function of smooth targets), in training-std units ``z = y / σ``::

    min_y  ‖f(y) − x*‖² + μ² ‖(y − g) / σ‖²

solved by the same damped least squares (:func:`rigmap.refine.damped_least_squares`) on a
rig with extra output rows ``μ·y/σ`` whose targets are ``μ·g/σ``: stacking ``μI`` under
``J`` is exactly the regularised normal equations ``(JᵀJ + μ²I)Δz = Jᵀr + μ²(z_g − z)``.
Well determined controls still follow the targets (their rows of ``JᵀJ`` are large in cm²
per std²), poorly determined ones stay at the guess. ``μ`` is in cm per training std; its
default (:data:`DEFAULT_PRIOR_WEIGHT`) is ours, chosen on the CMU walks (the paper gives
none).

The Jacobian is forward finite differences (one rig evaluation per used control, half of
central differences; its error, of the order of the step, is far below a cm: 1e-6 on a
float64 rig, 1e-3 on a rig that computes in float32, e.g. Blender's).
"""

from __future__ import annotations

import numpy as np

from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.refine import ComputedJacobian, damped_least_squares
from rigmap.rigs.base import Pose, Rig

DEFAULT_PRIOR_WEIGHT = 1.0  # μ, cm of joint error worth one training std of a control (ours)


class PriorRig(Rig):
    """A world-subset rig whose outputs also hold ``weights · y_used`` as pseudo joints;
    ``joint_weights`` (one per joint of ``view``, default 1) scale the joints' own rows."""

    def __init__(self, view: WorldSubsetRig, weights: np.ndarray, joint_weights=None):
        weights = np.asarray(weights, dtype=np.float64)
        n_joints = len(view.joint_names)
        self.joint_weights = (
            np.ones(n_joints)
            if joint_weights is None
            else np.asarray(joint_weights, dtype=np.float64)
        )
        if self.joint_weights.shape != (n_joints,) or not (self.joint_weights > 0).all():
            raise ValueError(f"joint weights must be {n_joints} numbers > 0")
        n_used = len(view.controls.used_indices)
        if weights.shape != (n_used,) or not np.isfinite(weights).all():
            raise ValueError(f"prior weights must be {n_used} finite numbers, got {weights.shape}")
        self.inner = view
        self.name = view.name
        self.controls = view.controls
        self.weights = weights
        self.n_prior = -(-n_used // 3)  # pseudo joints of three rows each (zero padded)
        self.joint_names = [*view.joint_names, *(f"prior_{k}" for k in range(self.n_prior))]
        self.parents = None
        self.differentiable = False
        self.computes_in_float32 = view.computes_in_float32
        self.length_unit = view.length_unit
        self.description = f"{view.description}, plus a prior on {n_used} controls"

    def prior_rows(self, Y_used: np.ndarray) -> np.ndarray:
        """``(N, P, 3)`` pseudo joints ``weights · y_used`` (zero padded)."""
        Y_used = np.asarray(Y_used, dtype=np.float64)
        rows = np.zeros((len(Y_used), 3 * self.n_prior))
        rows[:, : Y_used.shape[1]] = Y_used * self.weights
        return rows.reshape(len(Y_used), self.n_prior, 3)

    def _pose(self, Y) -> Pose:
        Y = np.asarray(Y, dtype=np.float64)
        world = np.asarray(self.inner.evaluate(Y), dtype=np.float64) * self.joint_weights[:, None]
        prior = self.prior_rows(Y[:, self.controls.used_indices])
        positions = np.concatenate([world, prior], axis=1)
        n = len(Y)
        return Pose(positions, np.zeros((n, 3)), np.broadcast_to(np.eye(3), (n, 3, 3)))


def refine_toward_guess(
    rig: Rig,
    joints,
    guess: np.ndarray,
    world: np.ndarray,
    *,
    prior_weight: float,
    control_scale: np.ndarray,
    damping: float | str,
    iterations: int,
    joint_weights=None,
):
    """Refine used controls ``guess`` ``(N, U)`` onto world targets ``(N, K, 3)`` of
    ``joints`` with the prior term ``prior_weight² ‖(y − guess)/σ‖²``; controls with scale 0
    (held, or never moved in training) stay; ``joint_weights`` (per joint, default 1)
    weigh the joints' errors, e.g. planted feet above the rest. Returns
    :class:`rigmap.refine.RefineResult` (its errors include the prior rows)."""
    if not (np.isfinite(prior_weight) and prior_weight >= 0):
        raise ValueError(f"prior weight {prior_weight!r} must be a finite number >= 0")
    scale = np.asarray(control_scale, dtype=np.float64)
    moving = scale > 0
    weights = np.where(moving, prior_weight / np.where(moving, scale, 1.0), 0.0)
    view = PriorRig(WorldSubsetRig(rig, joints), weights, joint_weights)
    world = np.asarray(world, dtype=np.float64) * view.joint_weights[:, None]
    targets = np.concatenate([world, view.prior_rows(guess)], axis=1)
    return damped_least_squares(
        view,
        guess,
        targets,
        ComputedJacobian(view, differences="forward"),
        damping=damping,
        max_iterations=iterations,
        control_scale=scale,
        keep_in_range=True,
    )
