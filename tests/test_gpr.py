"""GPR inverse mapping (§4.1-4.2) on a smooth synthetic rig: a planar three-link arm.

The "rig" maps three joint angles (radians) to the 2-D positions of the
elbow, wrist and fingertip (unit-free lengths 1.0, 0.8, 0.5); the GPR learns
the inverse, positions -> angles, over a range where it is single-valued.
"""

from __future__ import annotations

import json
from itertools import pairwise
from types import SimpleNamespace

import numpy as np
import pytest
from hydra.utils import instantiate

from rigmap.regression import (
    GaussianKernel,
    GaussianProcessRegressor,
    LinearKernel,
    ModelFileError,
    ModelMismatchError,
    MultiquadricKernel,
    PolynomialKernel,
    RegressionInputError,
    load_regressor,
    solve_regularized,
)
from rigmap.regression.normalisation import column_scale
from rigmap.regression.subsampling import greedy_subsample
from rigmap.rigs import RigInputError

LENGTHS = (1.0, 0.8, 0.5)
CONTROL_NAMES = ("shoulder.rz", "elbow.rz", "wrist.rz")
REST = np.array([0.0, 0.6, 0.4])


def arm_positions(angles: np.ndarray) -> np.ndarray:
    """``(N, 3)`` angles -> ``(N, 6)`` elbow, wrist and tip positions."""
    heading = np.cumsum(angles, axis=1)
    steps = np.stack([np.cos(heading), np.sin(heading)], axis=2) * np.array(LENGTHS)[:, None]
    return np.cumsum(steps, axis=1).reshape(len(angles), -1)


def arm_data(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    angles = np.column_stack(
        [rng.uniform(-0.8, 0.8, n), rng.uniform(0.2, 1.4, n), rng.uniform(0.1, 1.0, n)]
    )
    angles[0] = REST
    return arm_positions(angles), angles


@pytest.fixture(scope="module")
def train():
    return arm_data(400, seed=0)


@pytest.fixture(scope="module")
def fitted(train):
    X, Y = train
    return GaussianProcessRegressor(n_points=120, seed=3).fit(
        X, Y, rig_name="arm", control_names=CONTROL_NAMES
    )


def test_predicts_unseen_poses_of_the_arm(fitted):
    X_test, Y_test = arm_data(200, seed=1)
    error = np.mean((fitted.predict(X_test) - Y_test) ** 2)
    assert error < 1e-4  # radians^2; the angles themselves spread ~0.1 rad^2
    assert fitted.solver_ == "lu"


# theta1 = 1e-8 leaves the Gram matrix nearly singular, which the model rightly warns about
@pytest.mark.filterwarnings("ignore:GaussianProcessRegressor. the support system is nearly")
@pytest.mark.parametrize(
    "kernel",
    [MultiquadricKernel(), GaussianKernel(), PolynomialKernel(degree=3)],
    ids=lambda k: k.name,
)
def test_reproduces_training_targets_as_regularisation_goes_to_zero(train, kernel):
    X, Y = train[0][:60], train[1][:60]
    kernel = kernel.with_length_scale(1.0)
    errors = []
    for theta1 in (1e-1, 1e-3, 1e-5, 1e-8):
        model = GaussianProcessRegressor(
            kernel=kernel, regularization=theta1, n_points=None, search_length_scale=False
        ).fit(X, Y)
        errors.append(np.abs(model.predict(X) - Y).max())
    assert all(a > b for a, b in pairwise(errors)), errors
    assert errors[-1] < 1e-5


def test_multiquadric_stays_finite_with_near_duplicate_points(train):
    X, Y = train[0][:80], train[1][:80]
    rng = np.random.default_rng(4)
    # every pose three times, two copies jittered by 1e-10 (far below the data spread ~1)
    X_dup = np.concatenate([X, X + 1e-10 * rng.normal(size=X.shape), X.copy()])
    Y_dup = np.concatenate([Y, Y, Y])
    model = GaussianProcessRegressor(n_points=None, seed=0).fit(X_dup, Y_dup)
    X_test, Y_test = arm_data(50, seed=5)
    prediction = model.predict(X_test)
    assert np.isfinite(model.weights_).all()
    assert np.isfinite(prediction).all()
    assert np.mean((prediction - Y_test) ** 2) < 1e-2  # radians^2
    assert np.abs(model.predict(X) - Y).max() < 0.05  # radians, at the duplicated poses


def test_warns_when_the_support_system_is_nearly_singular(train):
    X, Y = train[0][:100], train[1][:100]
    # a very wide Gaussian without regularisation: numerically rank deficient
    model = GaussianProcessRegressor(
        kernel=GaussianKernel(100.0), regularization=0.0, n_points=None, search_length_scale=False
    )
    with pytest.warns(RuntimeWarning, match="nearly singular"):
        model.fit(X, Y)
    assert model.rcond_ < 1e-12
    assert np.isfinite(model.predict(X)).all()


def test_solver_falls_back_to_least_squares_on_a_singular_system():
    K = np.ones((4, 4))  # rank one: LU is singular without regularisation
    Y = np.arange(4.0)[:, None]
    W, solver, rcond = solve_regularized(K, Y, regularization=0.0)
    assert rcond < 1e-13
    assert solver == "lstsq"
    assert np.isfinite(W).all()
    np.testing.assert_allclose(K @ W, np.full((4, 1), Y.mean()), atol=1e-9)  # best fit


def test_length_scale_search_picks_an_interior_value_better_than_both_ends(fitted):
    scales, errors = fitted.length_scales_, fitted.cv_errors_
    assert (
        len(scales) == 25 and scales[0] == pytest.approx(1e-4) and scales[-1] == pytest.approx(1e2)
    )
    best = int(np.argmin(errors))
    assert 0 < best < len(scales) - 1
    assert 1e-4 < fitted.length_scale_ < 1e2
    assert fitted.length_scale_ == scales[best] == fitted.kernel_.length_scale
    assert errors[best] < errors[0] and errors[best] < errors[-1]


def test_subsampling_starts_with_the_rest_pose_and_returns_the_requested_count(train):
    X, Y = train
    rest = 17
    X, Y = X.copy(), Y.copy()
    X[[0, rest]], Y[[0, rest]] = X[[rest, 0]], Y[[rest, 0]]
    model = GaussianProcessRegressor(n_points=90, n_farthest=5, seed=1).fit(X, Y, rest_index=rest)
    support = model.support_indices_
    assert support[0] == rest
    assert len(support) == 90 == len(np.unique(support))
    np.testing.assert_allclose(model.support_points(), X[support])
    # Eq. 7: the first farthest point is the pose farthest from the rest pose
    Xn = (X - model.x_mean_) / model.x_std_
    assert support[1] == np.argmax(np.linalg.norm(Xn - Xn[rest], axis=1))
    # the greedy picks drive the worst training error down
    assert model.selection_errors_[-1] < 0.1 * model.selection_errors_[0]


def test_greedy_step_picks_the_point_a_direct_gpr_predicts_worst(train):
    """The incremental elimination must agree with refitting from scratch (Eq. 10)."""
    X, Y = train[0][:200], train[1][:200]
    x_mean, x_std = column_scale(X)
    y_mean, y_std = column_scale(Y)
    Xn, Yn = (X - x_mean) / x_std, (Y - y_mean) / y_std
    kernel = MultiquadricKernel(0.3)
    result = greedy_subsample(Xn, Yn, kernel, 1e-5, n_points=40, n_farthest=4)
    for m in (5, 20, 39):  # support size before the pick being checked
        chosen = result.indices[:m]
        W = solve_regularized(kernel(Xn[chosen]), Yn[chosen], 1e-5).weights
        residual = np.linalg.norm(Yn - kernel(Xn, Xn[chosen]) @ W, axis=1)
        residual[chosen] = -1.0
        assert result.indices[m] == np.argmax(residual)
        assert result.max_errors[m - 5] == pytest.approx(residual.max(), rel=1e-6)


def test_candidate_pool_bounds_the_rows_the_greedy_step_sees(train):
    X, Y = train
    model = GaussianProcessRegressor(n_points=50, max_candidates=100, seed=2).fit(X, Y)
    assert len(model.support_indices_) == 50
    assert model.support_indices_[0] == 0


@pytest.mark.parametrize("kernel", [GaussianKernel(), LinearKernel()], ids=lambda k: k.name)
def test_other_kernels_fit_and_predict(train, kernel):
    X, Y = train
    model = GaussianProcessRegressor(kernel=kernel, n_points=80, n_length_scales=9).fit(X, Y)
    X_test, Y_test = arm_data(100, seed=6)
    error = np.mean((model.predict(X_test) - Y_test) ** 2)
    baseline = np.mean((Y_test - Y.mean(axis=0)) ** 2)
    assert error < 0.2 * baseline  # even the linear kernel beats the mean


def test_single_output_and_single_row_shapes(train):
    X, Y = train
    model = GaussianProcessRegressor(n_points=60, n_length_scales=7).fit(X, Y[:, 1])
    assert model.predict(X[:5]).shape == (5,)
    assert np.ndim(model.predict(X[0])) == 0
    assert abs(model.predict(X[0]) - Y[0, 1]) < 1e-3


def test_same_seed_same_model(train):
    X, Y = train
    a = GaussianProcessRegressor(n_points=40, n_length_scales=5, seed=7).fit(X, Y)
    b = GaussianProcessRegressor(n_points=40, n_length_scales=5, seed=7).fit(X, Y)
    np.testing.assert_array_equal(a.support_indices_, b.support_indices_)
    np.testing.assert_array_equal(a.predict(X[:10]), b.predict(X[:10]))


# ----------------------------------------------------------------------------- bad input
def test_predict_rejects_wrong_width_naming_the_expected_shape(fitted, train):
    with pytest.raises(RegressionInputError, match=r"rig 'arm': expected inputs of shape \(M, 6\)"):
        fitted.predict(train[0][:, :4])


def test_predict_rejects_nan_naming_row_and_column(fitted, train):
    X = train[0][:10].copy()
    X[3, 2] = np.nan
    with pytest.raises(RigInputError, match=r"NaN or infinity \(first at row 3, column 2\)"):
        fitted.predict(X)


@pytest.mark.parametrize(
    ("X", "Y", "message"),
    [
        (np.zeros((10, 3)), np.zeros((9, 2)), "X has 10 rows but Y has 9"),
        (np.zeros((10, 3, 1)), np.zeros((10, 2)), r"expected inputs X of shape \(N, D\)"),
        (np.full((10, 3), np.inf), np.zeros((10, 2)), "inputs X contain NaN or infinity"),
        (np.array([["a"]]), np.zeros((1, 1)), "expected numbers"),
    ],
)
def test_fit_rejects_bad_training_data(X, Y, message):
    with pytest.raises(RegressionInputError, match=message):
        GaussianProcessRegressor().fit(X, Y)


def test_fit_rejects_control_names_of_the_wrong_length(train):
    with pytest.raises(RegressionInputError, match="expected 3 names"):
        GaussianProcessRegressor(n_points=10).fit(*train, control_names=["a", "b"])


def test_unfitted_model_says_so():
    with pytest.raises(RuntimeError, match="not fitted"):
        GaussianProcessRegressor().predict(np.zeros((1, 6)))


# ----------------------------------------------------------------------------- save / load
def test_save_load_round_trip_predicts_identically(fitted, train, tmp_path):
    fitted.save(tmp_path / "model")
    assert sorted(p.name for p in (tmp_path / "model").iterdir()) == ["gpr.json", "gpr.npz"]
    loaded = GaussianProcessRegressor.load(tmp_path / "model", rig="arm")
    np.testing.assert_array_equal(loaded.predict(train[0][:50]), fitted.predict(train[0][:50]))
    assert loaded.kernel_ == fitted.kernel_
    assert loaded.fingerprint_ == fitted.fingerprint_
    assert isinstance(load_regressor(tmp_path / "model"), GaussianProcessRegressor)


def test_loading_for_another_rig_fails_naming_both(fitted, tmp_path):
    fitted.save(tmp_path)
    with pytest.raises(ModelMismatchError, match="fitted for rig 'arm', but it is used with rig"):
        GaussianProcessRegressor.load(tmp_path, rig="quadruped")
    other_controls = SimpleNamespace(name="arm", control_names=["shoulder.rz", "elbow.rz"])
    with pytest.raises(ModelMismatchError, match=r"does not have: \['wrist.rz'\]"):
        GaussianProcessRegressor.load(tmp_path, rig=other_controls)


def test_fingerprint_checks_a_real_rig(train, quadruped, biped, tmp_path):
    names = quadruped.used_controls[:3]
    model = GaussianProcessRegressor(n_points=20, n_length_scales=3)
    model.fit(*train, rig_name=quadruped.name, control_names=names).save(tmp_path)
    loaded = GaussianProcessRegressor.load(tmp_path, rig=quadruped)
    assert loaded.fingerprint_.control_names == tuple(names)
    with pytest.raises(ModelMismatchError, match=r"fitted for rig 'quadruped'.*rig 'biped'"):
        GaussianProcessRegressor.load(tmp_path, rig=biped)


def test_corrupt_or_missing_model_files_are_reported(fitted, tmp_path):
    with pytest.raises(ModelFileError, match="no gpr model here"):
        GaussianProcessRegressor.load(tmp_path / "nothing")
    fitted.save(tmp_path)
    (tmp_path / "gpr.npz").write_bytes(b"truncated")
    with pytest.raises(ModelFileError, match="do not match the hash"):
        GaussianProcessRegressor.load(tmp_path)
    meta = json.loads((tmp_path / "gpr.json").read_text())
    meta["kind"] = "network"
    (tmp_path / "gpr.json").write_text(json.dumps(meta))
    with pytest.raises(ModelFileError, match="'kind' is 'network', expected 'gpr'"):
        GaussianProcessRegressor.load(tmp_path)


def test_save_leaves_no_temporary_files(fitted, tmp_path):
    fitted.save(tmp_path)
    fitted.save(tmp_path)  # overwrite in place
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gpr.json", "gpr.npz"]


# ----------------------------------------------------------------------------- configs
@pytest.mark.parametrize("kernel", ["multiquadric", "gaussian", "linear", "polynomial"])
def test_hydra_configs_build_the_regressor_with_the_papers_defaults(kernel):
    from hydra import compose, initialize

    with initialize(config_path="../conf", version_base="1.3"):
        cfg = compose("config", overrides=["regressor=gpr", f"kernel={kernel}", "experiment=paper"])
    model = instantiate(cfg.regressor)
    assert isinstance(model, GaussianProcessRegressor)
    assert model.kernel.name == kernel
    assert (model.n_points, model.regularization, model.cv_splits) == (750, 1e-5, 10)
    # the multiquadric searches the paper's range; the other kernels six decades higher
    expected = (1e-4, 1e2) if kernel == "multiquadric" else (1e-2, 1e4)
    assert model.length_scale_range is None and model.search_range == expected


def test_a_saved_kernel_mapping_builds_the_kernel():
    model = GaussianProcessRegressor(kernel={"name": "gaussian", "length_scale": 2.0}, n_points=5)
    assert model.get_params()["kernel"] == {"name": "gaussian", "length_scale": 2.0}
    from rigmap.regression.model_io import params_from_file

    rebuilt = GaussianProcessRegressor(**params_from_file(model.get_params(), ("kernel",)))
    assert rebuilt.kernel == GaussianKernel(2.0)
