"""Coloured (Curtis-Powell-Reid) Jacobians against dense ones on the built-in rigs (#16).

The poses are a built-in rig's test clips (never seen by the pattern probe), so
a structural entry the probe missed would show as a difference.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.animation.library import build_corpus
from rigmap.evaluation.metrics import control_std
from rigmap.refine import (
    ColumnColouring,
    ComputedJacobian,
    damped_least_squares,
    jacobian,
    rig_colouring,
)
from rigmap.refine.sparsity import probe_pattern
from rigmap.rigs.base import RigInputError


def _test_poses(rig, every: int = 37) -> np.ndarray:
    test = build_corpus(rig, "test", seed=0).table[rig.used_controls].to_numpy(float)
    return rig.expand_used(test[::every])


@pytest.fixture(params=["quadruped", "biped"])
def rig(request):
    return request.getfixturevalue(request.param)


def test_colouring_is_structurally_orthogonal_and_meets_the_clique_bound(rig):
    colouring = rig_colouring(rig)
    pattern = colouring.pattern
    for group in colouring.groups():
        # no row is touched by two controls of one colour
        assert pattern[:, group].sum(axis=1).max() <= 1
    assert (colouring.colours[~pattern.any(axis=0)] == -1).all()
    assert (colouring.colours[pattern.any(axis=0)] >= 0).all()
    # a row's controls all need their own colour: greedy reaches that bound on these rigs
    assert colouring.n_colours == pattern.sum(axis=1).max()
    assert colouring.n_colours < len(rig.controls.used_indices) / 4


@pytest.mark.parametrize("differences", ["forward", "central"])
def test_coloured_jacobian_equals_the_dense_one(rig, differences):
    Y = _test_poses(rig)
    colouring = rig_colouring(rig)
    dense = jacobian(rig, Y, differences=differences, chunk=64)
    coloured = jacobian(rig, Y, differences=differences, chunk=64, colouring=colouring)
    scale = np.abs(dense).max()
    assert scale > 1.0
    np.testing.assert_allclose(coloured, dense, rtol=0, atol=1e-6)


@pytest.mark.parametrize("coloured", [False, True])
def test_forward_differences_from_known_positions_equal_the_full_ones(rig, coloured):
    """Positions at Y given (refinement's residual): the same Jacobian, one pose fewer each."""
    from rigmap.evaluation.timing import CountingRig

    Y = _test_poses(rig)
    colouring = rig_colouring(rig) if coloured else None
    counting = CountingRig(rig)
    full = jacobian(counting, Y, differences="forward", chunk=64, colouring=colouring)
    full_poses = counting.reset().poses
    base = rig.evaluate(Y)
    known = jacobian(counting, Y, differences="forward", chunk=64, colouring=colouring, base=base)
    assert counting.count.poses == full_poses - len(Y)
    assert np.abs(full).max() > 1.0
    np.testing.assert_allclose(known, full, rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="forward differences only"):
        jacobian(rig, Y, differences="central", base=base)
    with pytest.raises(RigInputError, match="base must be the positions at Y"):
        jacobian(rig, Y, differences="forward", base=base[:-1])


def test_refinement_hands_its_residual_positions_to_forward_differences(quadruped):
    """The refined result is the same whether the source re-evaluates the poses or not."""
    rig = quadruped
    train = build_corpus(rig, "train", seed=0).table[rig.used_controls].to_numpy(float)
    test = build_corpus(rig, "test", seed=0).table[rig.used_controls].to_numpy(float)
    std = control_std(train)
    truth = test[10:14]
    start = truth + 0.5 * std * np.random.default_rng(1).standard_normal(truth.shape)
    target = rig.evaluate(rig.expand_used(truth))

    class Forgetful(ComputedJacobian):
        def uses_base(self):  # the poses evaluated again, as before
            return False

    results = {}
    for name, kind in (("known", ComputedJacobian), ("evaluated", Forgetful)):
        source = kind(rig, differences="forward", sparsity="coloured")
        results[name] = damped_least_squares(
            rig, start, target, source, damping="auto", tolerance=1e-4, max_iterations=3,
            control_scale=std, keep_in_range=True,
        )  # fmt: skip
    known, evaluated = results["known"], results["evaluated"]
    np.testing.assert_allclose(known.joint_error, evaluated.joint_error, rtol=1e-6, atol=1e-9)
    moved = np.abs(known.Y_used - evaluated.Y_used) / np.where(std > 0, std, 1.0)
    assert moved.max() < 1e-6
    # three Jacobians of four frames, each one pose cheaper
    assert evaluated.rig_evaluations - known.rig_evaluations == 3 * len(truth)
    assert known.joint_error.mean() < 0.1 * known.initial_joint_error.mean()


def test_coloured_autodiff_equals_the_dense_one(quadruped):
    Y = _test_poses(quadruped, every=400)
    colouring = rig_colouring(quadruped)
    dense = jacobian(quadruped, Y, method="autodiff")
    coloured = jacobian(quadruped, Y, method="autodiff", colouring=colouring)
    np.testing.assert_allclose(coloured, dense, rtol=0, atol=1e-9)


def test_a_missing_entry_in_the_pattern_changes_the_jacobian(quadruped):
    # the test above can fail: colour two controls that share rows alike and it does
    colouring = rig_colouring(quadruped)
    pattern = colouring.pattern
    a, b = np.flatnonzero(pattern[0])[:2]  # two controls moving joint 0's x
    colours = colouring.colours.copy()
    colours[b] = colours[a]
    wrong = ColumnColouring(pattern, colours)
    Y = _test_poses(quadruped, every=400)
    dense = jacobian(quadruped, Y, differences="forward")
    clashing = jacobian(quadruped, Y, differences="forward", colouring=wrong)
    assert np.abs(clashing - dense).max() > 1e-3


def test_probe_pattern_holds_every_entry_the_test_poses_move(rig):
    Y = _test_poses(rig)
    dense = np.abs(jacobian(rig, Y, differences="central", chunk=64))
    outside = dense[:, ~probe_pattern(rig)]
    assert outside.size and outside.max() < 1e-6


def test_coloured_refinement_gives_the_dense_result_with_fewer_evaluations(quadruped):
    # at a fixed λ: with "auto" the dense Jacobian's rounding noise (1e-8) in the columns of
    # controls that move nothing hides their exact zeros, so its σ_min is estimated (λ 0.9995)
    # where the coloured one's is exactly 0 (λ = 1), and the steps differ by that
    rig = quadruped
    train = build_corpus(rig, "train", seed=0).table[rig.used_controls].to_numpy(float)
    test = build_corpus(rig, "test", seed=0).table[rig.used_controls].to_numpy(float)
    std = control_std(train)
    truth = test[40:43]
    start = truth + 0.5 * std * np.random.default_rng(0).standard_normal(truth.shape)
    target = rig.evaluate(rig.expand_used(truth))
    results = {}
    for sparsity in ("dense", "coloured"):
        source = ComputedJacobian(rig, differences="forward", sparsity=sparsity)
        results[sparsity] = damped_least_squares(
            rig, start, target, source, damping=1.0, tolerance=1e-4, max_iterations=3,
            control_scale=std, keep_in_range=True,
        )  # fmt: skip
    dense, coloured = results["dense"], results["coloured"]
    # finite differences' rounding (1e-8) grows through three steps to ~1e-6 of a std
    moved = np.abs(coloured.Y_used - dense.Y_used) / np.where(std > 0, std, 1.0)
    assert moved.max() < 1e-4
    np.testing.assert_allclose(coloured.joint_error, dense.joint_error, rtol=1e-4, atol=1e-9)
    assert coloured.joint_error.mean() < 0.1 * coloured.initial_joint_error.mean()
    assert coloured.rig_evaluations * 4 < dense.rig_evaluations


def test_learned_jacobian_predicts_only_its_non_zero_entries_and_matches_the_full_gpr():
    from rigmap.regression.learned_jacobian import LearnedJacobian

    rng = np.random.default_rng(0)
    X = rng.standard_normal((40, 5))
    J = rng.standard_normal((40, 6, 4))
    J[:, :3, 2:] = 0.0  # a block no training Jacobian moves
    model = LearnedJacobian(search_length_scale=False).fit(X, J)
    queries = rng.standard_normal((7, 5))
    full = model.regressor_.predict(queries).reshape(7, 6, 4)
    np.testing.assert_allclose(model.predict(queries), full, rtol=1e-12, atol=1e-12)
    assert not model.pattern()[:3, 2:].any() and model.pattern()[3:].all()
    assert (model.predict(queries)[:, :3, 2:] == 0).all()


def test_refine_settings_read_sparsity_and_threads_and_name_a_bad_value():
    from rigmap.evaluation import RefineSettings
    from rigmap.evaluation.methods import EvaluationSetupError, get_method

    method = get_method("nn_computed_jacobian")
    config = {"name": "computed_jacobian", "jacobian": "finite_difference", "damping": "auto",
              "tolerance": 1e-4, "max_iterations": 3, "sparsity": "coloured",
              "threads": None}  # fmt: skip
    settings = RefineSettings.from_config(config, method)
    assert settings.sparsity == "coloured" and settings.threads is None
    with pytest.raises(EvaluationSetupError, match=r"refine\.sparsity"):
        RefineSettings.from_config({**config, "sparsity": "sparse"}, method)
    with pytest.raises(EvaluationSetupError, match=r"refine\.threads"):
        RefineSettings.from_config({**config, "threads": 0}, method)
