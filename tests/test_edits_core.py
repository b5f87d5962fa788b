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
            np.testing.assert_allclose(
                combine(*problem, weights, priors=priors),
                combine_dense(*problem, weights, priors=priors),
                rtol=1e-9,
                atol=1e-9,
            )


def test_a_frame_at_the_prior_variance_weighs_prediction_and_source_equally():
    """With the regulariser in units of the prior variance (§4.3's constant, ours), a frame
    whose kinematic variance equals the prior lands halfway between prediction and source,
    whatever the prior's size; the literal §4.3 (priors 1) gives the prediction alone for a
    small prior."""
    source, km, _, _, _ = clip_problem()
    frames = len(source)
    only = Weights(1.0, 1.0, 0.0, 0.0)
    for prior in (1e-3, 1.0, 50.0):
        solved = combine(
            source,
            km,
            np.full(frames, prior),
            km[1:-1],
            np.ones(frames - 2),
            only,
            priors=(prior, 1.0),
        )
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
        "leak_cm,context_correlation_with_speed\narm_swing,0.000249,0.000345,2.37,2.84,0.376,,"
        "0.912\n"
    )
    (table,) = edits_tables(tmp_path)
    assert table.name == "table_edits"
    assert table.rows == [
        ["Biped", "arm_swing", "0.000249", "0.000345", "2.37", "2.84", "0.38", "—", "0.91"]
    ]


def s28_objective(gp: SharedGP, theta):
    """The objective as SciPy's wrappers computed it up to s28 (``dpotri``, ``dpotrs`` and
    ``dsyrk`` holding the GIL), the reference for :mod:`rigmap.edits.nogil`'s path."""
    from scipy.linalg import blas, cho_factor, cho_solve, lapack

    length, signal, noise = np.exp(theta)
    n, d = gp.Y_.shape
    sq = gp._sq
    rbf = np.exp(-0.5 * sq / length**2)
    rbf *= signal**2
    K = rbf.copy()
    K[np.diag_indices_from(K)] += noise**2 + 1e-10
    factor = cho_factor(K, lower=True, overwrite_a=True, check_finite=False)
    A = cho_solve(factor, gp.Y_, check_finite=False)
    log_det = 2.0 * np.log(np.diag(factor[0])).sum()
    value = 0.5 * float((gp.Y_ * A).sum()) + 0.5 * d * log_det + 0.5 * n * d * np.log(2 * np.pi)
    inverse, info = lapack.dpotri(factor[0], lower=1, overwrite_c=1)
    assert info == 0
    inner = blas.dsyrk(1.0, A, lower=1)
    inverse *= d
    inner -= inverse
    trace = float(np.trace(inner))
    inner *= rbf
    inner *= gp._lower
    return value, np.array(
        [-0.5 * float(np.vdot(inner, sq)) / length**2, -float(inner.sum()), -(noise**2) * trace]
    )


@pytest.fixture(scope="module")
def cmu_edit_data():
    """The GPs' training data of ``benchmarks/edits.py`` at a third of its size: two
    stretches of the CMU walk with ``arms_forward_walking``, residual targets."""
    from pathlib import Path

    import yaml

    from rigmap.edits.procedural import Edit
    from rigmap.edits.representation import ChannelScale
    from rigmap.edits.subjects import skeleton_clip, skeleton_subject

    root = Path(__file__).resolve().parents[1]
    walk = root.parent / "shared/mocap/cmu_131_02_walk.bvh"
    subject = skeleton_subject(walk, 6.0, "cmu")
    clip = skeleton_clip(subject, walk)
    config = yaml.safe_load((root / "conf/edit/arms_forward_walking.yaml").read_text())
    edit = Edit.from_config("arms_forward_walking", config, "skeleton")
    scale = ChannelScale.fit([clip])
    xk, yk, xa, ya = [], [], [], []
    for segment in (clip.frames(100, 280), clip.frames(600, 780)):
        source = subject.source(segment)
        target = scale.scaled(edit.apply(segment, 6.0)) - scale.scaled(segment)
        kinematic, acceleration = source.features(subject.joints)
        xk.append(kinematic)
        yk.append(target)
        xa.append(acceleration[1:-1])
        ya.append(accelerations(target))
    return {
        "kinematic": (np.vstack(xk), np.vstack(yk)),
        "acceleration": (np.vstack(xa), np.vstack(ya)),
    }


def test_the_gil_free_lapack_calls_equal_scipys_wrappers_bit_for_bit(cmu_edit_data):
    from scipy.linalg import blas, cho_factor, lapack

    from rigmap.edits import nogil

    gp = SharedGP(optimize=False, center=False).fit(*cmu_edit_data["kinematic"])
    K = gp._gram(np.log([5.0, 0.5, 0.01]))
    factor = cho_factor(K, lower=True, check_finite=False)[0]
    assert factor.flags.f_contiguous
    A = nogil.potrs_lower(factor, gp.Y_)
    assert np.array_equal(A, lapack.dpotrs(factor, gp.Y_, lower=1)[0])
    assert np.array_equal(nogil.syrk_lower(A), blas.dsyrk(1.0, A, lower=1))
    expected, info = lapack.dpotri(factor.copy(order="F"), lower=1)
    assert info == 0 and nogil.potri_lower(factor) == 0
    assert np.array_equal(factor, expected)
    with pytest.raises(ValueError, match="Fortran-ordered square"):
        nogil.potri_lower(np.ascontiguousarray(K[:, :-1]))
    with pytest.raises(ValueError, match="rows"):
        nogil.potrs_lower(factor, gp.Y_[:-1])


@pytest.mark.parametrize("name", ["kinematic", "acceleration"])
def test_the_objective_and_the_fit_are_the_s28_ones_on_real_data(cmu_edit_data, name):
    """The GIL-free path changes where LAPACK runs, not what it computes: the objective and
    its gradient equal the s28 path's exactly, so the fitted optimum does too; and the
    gradient matches finite differences (the real data's ill-conditioned optimum aside)."""
    X, Y = cmu_edit_data[name]
    gp = SharedGP(optimize=False, center=False).fit(X, Y)
    for theta in (np.log([1.0, 1.0, 0.1]), np.log([20.0, 0.7, 1e-4]), np.log([2.4, 1e-3, 5e-5])):
        value, gradient = gp._objective(theta)
        expected = s28_objective(gp, theta)
        assert value == expected[0]
        assert np.array_equal(gradient, expected[1])

    class S28GP(SharedGP):
        def _objective(self, theta):
            return s28_objective(self, theta)

    new, old = SharedGP(center=False).fit(X, Y), S28GP(center=False).fit(X, Y)
    assert new.iterations_ == old.iterations_ > 5
    fitted = ("length_scale_", "signal_", "noise_", "log_marginal_likelihood_")
    assert [getattr(new, k) for k in fitted] == [getattr(old, k) for k in fitted]
    theta, step = np.log([3.0, 0.5, 0.05]), 1e-5
    numeric = [
        (gp._objective(theta + step * e)[0] - gp._objective(theta - step * e)[0]) / (2 * step)
        for e in np.eye(3)
    ]
    np.testing.assert_allclose(gp._objective(theta)[1], numeric, rtol=1e-5)


def test_a_hinge_joints_unused_axes_count_as_constant_channels():
    """The CMU knees are hinges: their z exponential map is rounding noise in training
    (std about 5e-7 rad), and bowed legs turn the knee about z. Divided by the noise, that
    edit measured millions of std units; as a constant channel the knee keeps radians."""
    from pathlib import Path

    import yaml

    from rigmap.edits.procedural import Edit
    from rigmap.edits.representation import NEAR_CONSTANT_FRACTION, ChannelScale
    from rigmap.edits.subjects import skeleton_clip, skeleton_subject

    root = Path(__file__).resolve().parents[1]
    walk = root.parent / "shared/mocap/cmu_131_01_walk.bvh"
    subject = skeleton_subject(walk, 6.0, "cmu")
    clip = skeleton_clip(subject, walk)
    scale = ChannelScale.fit([clip])
    raw = clip.values.std(axis=0)
    knee = clip.channels.index("LeftKnee.z")
    floor = NEAR_CONSTANT_FRACTION * np.median(raw[raw > 1e-12])
    assert 0 < raw[knee] < 1e-5 < floor
    kept = raw >= floor  # every channel that moves keeps its own std
    np.testing.assert_array_equal(scale.std[kept], raw[kept])
    np.testing.assert_array_equal(scale.std[~kept], 1.0)
    noise = (raw > 1e-12) & ~kept  # and only the hinges' noise joins the constant ones
    assert 0 < noise.sum() <= 6 and raw[noise].max() < 1e-5
    config = yaml.safe_load((root / "conf/edit/bowed_legs.yaml").read_text())
    edited = Edit.from_config("bowed_legs", config, "skeleton").apply(clip, 6.0, subject.skeleton)
    moved = np.abs(scale.scaled(edited) - scale.scaled(clip))
    assert moved[:, knee].max() == pytest.approx(0.4, rel=0.05)  # the 0.4 rad turn, in rad
    assert moved.max() < 100
