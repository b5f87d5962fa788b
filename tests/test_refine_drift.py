"""Refinement must lower the joint error without dragging controls away from an animator's (#7).

The problem is real: the rig's own training corpus gives each control's
standard deviation (the ground-truth error's scale), a few frames of its test
clips are the truth, their poses the targets, and the starting guess is the
truth off by half a training std per control — the size of a regressor's
mistakes. Plain Eq. 13 (λ in each control's own unit) reproduces the issue:
the joints get closer while FK rotations of limbs held in IK, which the
animators hardly moved, swing by radians.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.animation.library import build_corpus
from rigmap.evaluation.metrics import control_std, ground_truth_error
from rigmap.refine import ComputedJacobian, PredictedJacobian, damped_least_squares, jacobian
from rigmap.rigs import RigInputError

FRAMES = 4
ITERATIONS = 3  # the quick experiment's budget.refine_iterations


class RigProblem:
    def __init__(self, rig):
        used = rig.controls.used_indices
        train = build_corpus(rig, "train", seed=0).table[rig.used_controls].to_numpy(float)
        test = build_corpus(rig, "test", seed=0).table[rig.used_controls].to_numpy(float)
        self.rig = rig
        self.std = control_std(train)
        self.kinds = [rig.controls.kinds[i] for i in used]
        self.lower, self.upper = rig.controls.lower[used], rig.controls.upper[used]
        self.truth = test[np.linspace(0, len(test) - 1, FRAMES).astype(int)]
        rng = np.random.default_rng(0)
        self.start = self.truth + 0.5 * self.std * rng.standard_normal(self.truth.shape)
        self.target = rig.evaluate(rig.expand_used(self.truth))

    def ground_truth_error(self, Y_used) -> float:
        return ground_truth_error(Y_used, self.truth, self.std, self.kinds).mean

    def refine(self, start=None, source=None, **settings):
        return damped_least_squares(
            self.rig,
            self.start if start is None else start,
            self.target,
            source or ComputedJacobian(self.rig),
            tolerance=1e-4,
            max_iterations=ITERATIONS,
            **settings,
        )


_PROBLEMS: dict[str, RigProblem] = {}


def rig_problem(rig) -> RigProblem:
    """Built once per rig (two corpora and a few poses: about a second)."""
    if rig.name not in _PROBLEMS:
        _PROBLEMS[rig.name] = RigProblem(rig)
    return _PROBLEMS[rig.name]


@pytest.fixture(params=["quadruped", "biped"])
def problem(request) -> RigProblem:
    return rig_problem(request.getfixturevalue(request.param))


def test_normalised_refinement_lowers_joint_error_and_keeps_ground_truth_error(problem):
    """The conf/refine default: steps in training stds, Chiaverini λ, soft ranges kept."""
    result = problem.refine(control_scale=problem.std, damping="auto", keep_in_range=True)
    before, after = (
        problem.ground_truth_error(problem.start),
        problem.ground_truth_error(result.Y_used),
    )
    assert result.joint_error.mean() < 0.05 * result.initial_joint_error.mean()
    assert after < 1.5 * before  # bounded: the guess's own mistakes, not new ones
    assert after < 1.0  # within one training std (RMS) of the animator's values
    inside = (result.Y_used >= problem.lower - 1e-12) & (result.Y_used <= problem.upper + 1e-12)
    assert inside[(problem.start >= problem.lower) & (problem.start <= problem.upper)].all()


def test_plain_eq13_drifts_along_weak_fk_controls_the_animators_never_moved(problem):
    """The cause of #7: λ priced in radians lets controls with a tiny training std run off."""
    result = problem.refine(damping=0.1)
    before, after = (
        problem.ground_truth_error(problem.start),
        problem.ground_truth_error(result.Y_used),
    )
    assert result.joint_error.mean() < result.initial_joint_error.mean()
    assert after > 100 * before
    per_control = (((result.Y_used - problem.truth) / problem.std) ** 2).mean(axis=0)
    worst = np.argsort(-per_control)[:10]
    # ten controls carry most of the damage, and the animators hardly moved them: their
    # training stds sit among the smallest tenth (about 0.008 rad on both rigs)
    assert per_control[worst].sum() > 0.5 * per_control.sum()
    assert np.median(problem.std[worst]) < np.quantile(problem.std, 0.1)
    names = np.asarray(problem.rig.used_controls)[worst]
    assert sum("_fk." in name for name in names) >= 5, names


def test_scaling_also_bounds_a_fixed_predicted_jacobian(quadruped):
    """The learned-Jacobian path (one Jacobian per target, reused) takes the same scale."""
    problem = rig_problem(quadruped)
    truth = quadruped.expand_used(problem.truth[:2])

    class ExactAtTruth:  # stands in for a learned model: the rig's Jacobian at the answer
        def predict(self, X):
            return jacobian(quadruped, truth)

    start = problem.start[:2]
    target = problem.target[:2]
    result = damped_least_squares(
        quadruped,
        start,
        target,
        PredictedJacobian(ExactAtTruth()),
        damping="auto",
        tolerance=1e-4,
        max_iterations=ITERATIONS,
        control_scale=problem.std,
    )
    truth_error = ground_truth_error(result.Y_used, problem.truth[:2], problem.std, problem.kinds)
    initial = ground_truth_error(start, problem.truth[:2], problem.std, problem.kinds)
    assert result.joint_error.mean() < 0.2 * result.initial_joint_error.mean()
    assert truth_error.mean < 1.5 * initial.mean


def test_zero_scale_freezes_a_control_and_range_start_outside_is_not_pushed_further(quadruped):
    problem = rig_problem(quadruped)
    start = problem.start[:1].copy()
    moved = int(np.argmax(problem.std))  # the control the animators moved most
    outside = int(np.flatnonzero(problem.upper - problem.lower < 10)[0])
    start[0, outside] = problem.upper[outside] + 0.5  # a guess already past the soft range
    scale = problem.std.copy()
    scale[moved] = 0.0
    result = damped_least_squares(
        quadruped,
        start,
        problem.target[:1],
        ComputedJacobian(quadruped),
        damping="auto",
        tolerance=0.0,
        max_iterations=2,
        control_scale=scale,
        keep_in_range=True,
    )
    assert result.Y_used[0, moved] == start[0, moved]
    assert result.joint_error[0] < result.initial_joint_error[0]
    assert problem.lower[outside] <= result.Y_used[0, outside] <= start[0, outside]
    started_inside = (start[0] >= problem.lower) & (start[0] <= problem.upper)
    kept = result.Y_used[0, started_inside]
    assert (kept >= problem.lower[started_inside]).all()
    assert (kept <= problem.upper[started_inside]).all()


@pytest.mark.parametrize(
    ("scale", "message"),
    [
        (np.ones(5), r"control_scale of shape \(218,\).*got shape \(5,\)"),
        (-np.ones(218), r"minimum -1"),
        (np.full(218, np.nan), r"finite value >= 0"),
    ],
)
def test_bad_control_scale_is_refused(quadruped, scale, message):
    used = len(quadruped.used_controls)
    start = np.zeros((1, used))
    target = quadruped.evaluate(quadruped.expand_used(start))
    with pytest.raises(RigInputError, match=message):
        damped_least_squares(
            quadruped, start, target, ComputedJacobian(quadruped), control_scale=scale
        )
