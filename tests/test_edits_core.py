"""Edit propagation core (002): the shared-kernel GP and the banded combined solve."""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.edits.combine import (
    CombineError,
    Weights,
    accelerations,
    combine,
    combine_dense,
    second_difference,
)
from rigmap.edits.gp import GPInputError, SharedGP


def clip_problem(frames=60, outputs=4, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2 * np.pi, frames)[:, None]
    source = np.sin(t * np.arange(1, outputs + 1)) + 0.1 * rng.normal(size=(frames, outputs))
    km = source + 0.3 * rng.normal(size=source.shape)
    kv = rng.uniform(0.05, 2.0, frames)
    am = accelerations(source) + 0.01 * rng.normal(size=(frames - 2, outputs))
    av = rng.uniform(0.001, 0.05, frames - 2)
    return source, km, kv, am, av


def test_banded_solve_equals_the_dense_solve():
    problem = clip_problem()
    for weights in (Weights(), Weights(2.0, 0.5, 3.0, 0.1), Weights(1.0, 0.0, 1.0, 0.0)):
        for priors in ((1.0, 1.0), (0.3, 0.02)):
            np.testing.assert_allclose(combine(*problem, weights, priors=priors),
                                       combine_dense(*problem, weights, priors=priors),
                                       rtol=1e-9, atol=1e-9)  # fmt: skip


def test_a_frame_at_the_prior_variance_weighs_prediction_and_source_equally():
    """With the regulariser in units of the prior variance (§4.3's constant, ours), a frame
    whose kinematic variance equals the prior lands halfway between prediction and source,
    whatever the prior's size; the literal §4.3 (priors 1) gives the prediction alone for a
    small prior."""
    source, km, _, _, _ = clip_problem()
    frames = len(source)
    only = Weights(1.0, 1.0, 0.0, 0.0)
    for prior in (1e-3, 1.0, 50.0):
        solved = combine(source, km, np.full(frames, prior), km[1:-1], np.ones(frames - 2),
                         only, priors=(prior, 1.0))  # fmt: skip
        np.testing.assert_allclose(solved, 0.5 * (source + km), atol=1e-9)
    literal = combine(source, km, np.full(frames, 1e-3), km[1:-1], np.ones(frames - 2), only)
    assert np.abs(literal - km).max() < 1e-5


def test_a_noiseless_gps_tiny_variances_still_solve_without_the_kinematic_term():
    """Variances near 1e-16 (a GP fitted to noiseless examples) made the banded Cholesky
    fail when the kinematic weight was 0; raised to MIN_VARIANCE the system stays
    positive definite. Its accelerations follow the predictions in both solves; the
    offset and slope the weak anchor sets are ill-conditioned (about 1e-9 against 1e6)
    and are not compared."""
    source, km, kv, am, av = clip_problem()
    tiny = (source, km, np.full_like(kv, 1e-16), am, np.full_like(av, 1e-16))
    anchored = Weights(0.0, 1e-3, 1.0, 0.0)
    banded = combine(*tiny, anchored)
    assert np.isfinite(banded).all()
    np.testing.assert_allclose(accelerations(banded), am, atol=1e-6)
    np.testing.assert_allclose(accelerations(combine_dense(*tiny, anchored)), am, atol=1e-6)


def test_second_difference_matches_accelerations():
    values = np.random.default_rng(1).normal(size=(9, 2))
    np.testing.assert_allclose(second_difference(9) @ values, accelerations(values), atol=1e-15)


def test_zero_edit_returns_the_source_and_masks_hold():
    source, _, kv, _, av = clip_problem()
    same = combine(source, source, kv, accelerations(source), av)
    np.testing.assert_allclose(same, source, atol=1e-10)
    _, km, kv, am, av = clip_problem(seed=3)
    masked = np.array([True, False, True, False])
    edited = combine(source, km, kv, am, av, masked=masked)
    np.testing.assert_array_equal(edited[:, masked], source[:, masked])
    assert np.abs(edited[:, ~masked] - source[:, ~masked]).max() > 0.01


def test_unsure_frames_fall_back_to_the_source():
    source, km, _, _, _ = clip_problem()
    frames = len(source)
    am = accelerations(km)  # predictions that agree with each other
    sure = combine(source, km, np.full(frames, 1e-3), am, np.full(frames - 2, 1e-3))
    unsure = combine(source, km, np.full(frames, 1e3), am, np.full(frames - 2, 1e3))
    assert np.abs(sure - km).mean() < 0.01 * np.abs(source - km).mean()
    assert np.abs(unsure - source).mean() < 0.01 * np.abs(km - source).mean()


def test_bad_inputs_are_named():
    source, km, kv, am, av = clip_problem()
    with pytest.raises(CombineError, match=r"acceleration_mean has shape \(57, 4\)"):
        combine(source, km, kv, am[1:], av)
    with pytest.raises(CombineError, match="variances must be > 0"):
        combine(source, km, kv * 0, am, av)
    with pytest.raises(CombineError, match="weight acceleration is -1"):
        Weights(acceleration=-1)


def test_marginal_likelihood_gradient_matches_finite_differences():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(30, 3))
    Y = np.column_stack([np.sin(X[:, 0]), X[:, 1] * X[:, 2]]) + 0.05 * rng.normal(size=(30, 2))
    gp = SharedGP(optimize=False).fit(X, Y)
    theta = np.log([0.7, 1.3, 0.2])
    value, gradient = gp._objective(theta)
    step = 1e-6
    numeric = [
        (gp._objective(theta + step * e)[0] - gp._objective(theta - step * e)[0]) / (2 * step)
        for e in np.eye(3)
    ]
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5)
    assert np.isfinite(value)


def test_profile_fit_reaches_the_optimum_of_the_three_parameter_search():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 20, 300)
    X = np.column_stack([np.sin(t * k) for k in range(1, 12)]) + 0.05 * rng.normal(size=(300, 11))
    Y = np.column_stack([np.sin(2 * t) * X[:, 0], X[:, 1] ** 2, X[:, 3]])
    Y = Y + 0.05 * rng.normal(size=Y.shape)
    old = SharedGP(method="lbfgs").fit(X, Y)
    new = SharedGP(method="profile").fit(X, Y)
    for name in ("length_scale_", "signal_", "noise_"):
        assert getattr(new, name) == pytest.approx(getattr(old, name), rel=1e-3)
    assert new.log_marginal_likelihood_ == pytest.approx(old.log_marginal_likelihood_, rel=1e-8)
    theta = np.log([new.length_scale_, new.signal_, new.noise_])
    value, gradient = new._objective(theta)
    assert np.abs(gradient).max() < 1e-5 * abs(value)  # a stationary point of the 3-D objective
    assert new.evaluations_ < old.iterations_
    np.testing.assert_allclose(new.predict(X[:50]).mean, old.predict(X[:50]).mean, atol=1e-4)
    with pytest.raises(GPInputError, match="unknown GP fitting method"):
        SharedGP(method="cg")


def test_fitted_gp_predicts_with_variance_that_grows_away_from_data():
    rng = np.random.default_rng(3)
    X = rng.uniform(-2, 2, size=(80, 2))
    Y = np.column_stack([np.sin(2 * X[:, 0]), np.cos(X[:, 1])])
    gp = SharedGP().fit(X, Y + 0.01 * rng.normal(size=Y.shape))
    assert gp.iterations_ <= 100
    assert gp.log_marginal_likelihood_ > SharedGP(optimize=False).fit(X, Y).log_marginal_likelihood_
    inside = rng.uniform(-1.5, 1.5, size=(50, 2))
    truth = np.column_stack([np.sin(2 * inside[:, 0]), np.cos(inside[:, 1])])
    near = gp.predict(inside)
    assert np.abs(near.mean - truth).max() < 0.1
    far = gp.predict(np.array([[8.0, 8.0], [-9.0, 7.0]]))
    assert far.variance.min() > 20 * near.variance.max()
    np.testing.assert_allclose(far.mean, np.tile(gp.y_mean_, (2, 1)), atol=0.05)
    with pytest.raises(GPInputError, match="row 1, column 0"):
        gp.predict(np.array([[0.0, 0.0], [np.nan, 0.0]]))


def test_source_features_ignore_where_the_clip_walks_and_turns():
    from pathlib import Path

    from rigmap.edits.features import acceleration_features, kinematic_features
    from rigmap.map import tracks_from_bvh
    from rigmap.regression.placement import turn_matrix

    walk = Path(__file__).resolve().parents[1].parent / "shared/mocap/cmu_131_02_walk.bvh"
    tracks = tracks_from_bvh(walk)
    positions = tracks.positions[:300]
    names = tracks.joint_names
    root, left, right = names.index("Hips"), names.index("LeftHip"), names.index("RightHip")
    moved = np.einsum("ab,njb->nja", turn_matrix(np.array(2.0)), positions) + np.array(
        [40.0, 0, -7]
    )
    k1 = kinematic_features(positions, tracks.fps, root=root, left=left, right=right)
    k2 = kinematic_features(moved, tracks.fps, root=root, left=left, right=right)
    np.testing.assert_allclose(k1, k2, atol=1e-9)
    assert k1.shape == (300, 9 * len(names))
    a1 = acceleration_features(positions, tracks.fps, root=root)
    a2 = acceleration_features(positions + np.array([5.0, 0, 3.0]), tracks.fps, root=root)
    np.testing.assert_allclose(a1, a2, atol=1e-6)
    # the walk swings its limbs: accelerations of the wrists are far from zero
    wrist = names.index("LeftWrist")
    assert np.abs(a1[:, 3 * wrist : 3 * wrist + 3]).max() > 10.0


def test_the_report_tables_the_edit_metrics_that_exist(tmp_path):
    from rigmap.reports.edits_tables import edits_tables

    assert edits_tables(tmp_path) == []
    folder = tmp_path / "biped" / "edits"
    folder.mkdir(parents=True)
    (folder / "edits.csv").write_text(
        "edit,edit_error_std,source_error_std,joint_rmse_cm,source_joint_rmse_cm,transfer,"
        "leak_cm\narm_swing,0.000249,0.000345,2.37,2.84,0.376,\n"
    )
    (table,) = edits_tables(tmp_path)
    assert table.name == "table_edits"
    assert table.rows == [
        ["Biped", "arm_swing", "0.000249", "0.000345", "2.37", "2.84", "0.38", "—"]
    ]
