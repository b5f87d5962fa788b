"""Damped least squares (Eq. 13) on the built-in rigs."""

from __future__ import annotations

import numpy as np
import pytest

from rig_poses import random_used_controls
from rigmap.refine import (
    ComputedJacobian,
    PredictedJacobian,
    chiaverini_damping,
    damped_least_squares,
    jacobian,
)
from rigmap.rigs import RigInputError


def _problem(rig, n=3, seed=5, noise=0.05):
    """Targets from real poses; starting guesses perturbed in the used controls."""
    Y = random_used_controls(rig, n, seed=seed)
    used = rig.controls.used_indices
    target = rig.evaluate(Y)
    rng = np.random.default_rng(seed + 1)
    start = Y[:, used] + noise * rng.standard_normal((n, len(used)))
    return Y[:, used], start, target


@pytest.mark.parametrize(
    ("method", "frames", "iterations"), [("finite_difference", 2, 4), ("autodiff", 1, 2)]
)
def test_computed_jacobian_refinement_reduces_joint_error(biped, method, frames, iterations):
    _truth, start, target = _problem(biped, n=frames)
    result = damped_least_squares(
        biped,
        start,
        target,
        ComputedJacobian(biped, method),
        damping=0.05,
        tolerance=1e-8,
        max_iterations=iterations,
    )
    assert (result.joint_error < 0.05 * result.initial_joint_error).all()
    assert (result.iterations >= 1).all()
    # evaluations: one per frame per iteration (plus the start), and 2·C_used per
    # frame per iteration for finite differences
    iters = int(result.iterations.sum())
    per_jacobian = 2 * len(biped.used_controls) if method == "finite_difference" else 1
    assert result.rig_evaluations == frames + iters + iters * per_jacobian


def test_refinement_only_moves_used_controls_and_stops_at_tolerance(quadruped):
    _truth, start, target = _problem(quadruped, n=2, noise=0.02)
    result = damped_least_squares(
        quadruped,
        start,
        target,
        ComputedJacobian(quadruped),
        damping=0.05,
        tolerance=1e-3,
        max_iterations=20,
    )
    assert result.Y_used.shape == start.shape
    assert (result.joint_error < 1e-3).all()
    assert result.iterations.max() < 20  # stopped by the tolerance, not the cap


def test_a_fixed_predicted_jacobian_also_helps(biped):
    """The learned-Jacobian path: J predicted once at the target, reused every iteration."""
    truth, start, target = _problem(biped, n=2, noise=0.03)

    class ExactAtTruth:  # stands in for a learned model: the true Jacobian at the answer
        def predict(self, X):
            return jacobian(biped, biped.expand_used(truth))

    result = damped_least_squares(
        biped,
        start,
        target,
        PredictedJacobian(ExactAtTruth()),
        damping=0.05,
        tolerance=1e-10,
        max_iterations=5,
    )
    assert (result.joint_error < 0.1 * result.initial_joint_error).all()
    # no rig evaluations spent on Jacobians: only the error checks
    assert result.rig_evaluations == 2 + int(result.iterations.sum())


def test_chiaverini_damping_is_zero_away_from_singularities():
    s = np.array([[5.0, 2.0, 1.5], [5.0, 2.0, 0.5], [5.0, 2.0, 0.0]])
    lam = chiaverini_damping(s, epsilon=1.0, max_damping=0.8)
    assert lam[0] == 0.0
    assert 0.0 < lam[1] < 0.8
    assert lam[2] == pytest.approx(0.8)


def test_bad_refine_input(biped):
    _truth, start, target = _problem(biped, n=2)
    with pytest.raises(RigInputError, match=r"expected initial controls of shape \(2, 211\)"):
        damped_least_squares(biped, start[:, :10], target, ComputedJacobian(biped))
    bad = target.copy()
    bad[0, 3, 1] = np.nan
    with pytest.raises(RigInputError, match="NaN or infinity"):
        damped_least_squares(biped, start, bad, ComputedJacobian(biped))
    with pytest.raises(RigInputError, match=r"\(N, 73, 3\)"):
        damped_least_squares(biped, start, target[:, :5], ComputedJacobian(biped))
