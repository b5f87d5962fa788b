"""Feed-forward network inverse mapping (§5.3), on the planar three-link arm of test_gpr.

Small hidden layers and few samples keep every test well under a second or two.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hydra.utils import instantiate

from rigmap.regression import (
    FeedForwardRegressor,
    GaussianProcessRegressor,
    JointSpaceNetworkRegressor,
    LearnedJacobian,
    ModelFileError,
    ModelMismatchError,
    RegressionInputError,
    load_regressor,
)

LENGTHS = (1.0, 0.8, 0.5)
CONTROL_NAMES = ("shoulder.rz", "elbow.rz", "wrist.rz")
# One thread: steps this small are dominated by thread hand-offs on a busy 2-core machine.
FAST = {"progress": False, "threads": 1}


def arm_data(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Angles (radians) of a planar 3-link arm and its joint positions (elbow, wrist, tip)."""
    rng = np.random.default_rng(seed)
    angles = np.column_stack(
        [rng.uniform(-0.8, 0.8, n), rng.uniform(0.2, 1.4, n), rng.uniform(0.1, 1.0, n)]
    )
    heading = np.cumsum(angles, axis=1)
    steps = np.stack([np.cos(heading), np.sin(heading)], axis=2) * np.array(LENGTHS)[:, None]
    # offset and scale the positions so normalisation has something to undo (centimetres)
    positions = 100.0 + 30.0 * np.cumsum(steps, axis=1).reshape(n, -1)
    return positions, angles


@pytest.fixture(scope="module")
def trained():
    X, Y = arm_data(2000, seed=0)
    model = FeedForwardRegressor(
        hidden=128, epochs=8, batch_size=32, learning_rate=3e-3, seed=1, **FAST
    )
    return model.fit(X, Y, rig_name="arm", control_names=CONTROL_NAMES)


def test_overfits_a_tiny_set():
    X, Y = arm_data(16, seed=2)
    model = FeedForwardRegressor(
        hidden=256, alpha=0.0, epochs=300, batch_size=8, learning_rate=3e-3, **FAST
    ).fit(X, Y)
    spread = np.mean((Y - Y.mean(axis=0)) ** 2)
    assert np.mean((model.predict(X) - Y) ** 2) < 1e-3 * spread
    assert model.loss_history_[-1] < 1e-2 * model.loss_history_[0]


def test_learns_the_inverse_of_the_arm_on_unseen_poses(trained):
    X_test, Y_test = arm_data(300, seed=3)
    error = np.mean((trained.predict(X_test) - Y_test) ** 2)
    assert error < 2e-3  # radians^2; predicting the mean gives ~0.1
    assert trained.loss_history_[-1] < trained.loss_history_[0]


def test_predict_matches_the_network_on_normalised_data(trained):
    """Folding the standardisation into the weights must not change the function."""
    X, _ = arm_data(50, seed=4)
    with torch.no_grad():
        x = torch.from_numpy(((X - trained.x_mean_) / trained.x_std_).astype(np.float32))
        expected = trained.network_(x).double().numpy() * trained.y_std_ + trained.y_mean_
    np.testing.assert_allclose(trained.predict(X), expected, atol=1e-4)


def test_predict_shapes_and_dtype(trained):
    X, _ = arm_data(5, seed=5)
    out = trained.predict(X)
    assert out.shape == (5, 3) and out.dtype == np.float64
    assert trained.predict(X[0]).shape == (3,)
    np.testing.assert_allclose(trained.predict(X[0]), out[0], atol=1e-6)


def test_same_seed_same_network_and_other_seed_differs():
    X, Y = arm_data(64, seed=6)
    kwargs = dict(hidden=32, epochs=2, batch_size=8, **FAST)
    a = FeedForwardRegressor(seed=5, **kwargs).fit(X, Y).predict(X)
    b = FeedForwardRegressor(seed=5, **kwargs).fit(X, Y).predict(X)
    c = FeedForwardRegressor(seed=6, **kwargs).fit(X, Y).predict(X)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 1e-4


def test_l1_term_shrinks_the_weights_and_sum_reduction_shrinks_them_most():
    X, Y = arm_data(256, seed=7)
    kwargs = dict(hidden=64, epochs=10, batch_size=8, seed=0, **FAST)
    norms = {}
    for name, alpha, reduction in [
        ("none", 0.0, "mean"),
        ("mean", 0.1, "mean"),
        ("sum", 0.1, "sum"),
    ]:
        model = FeedForwardRegressor(alpha=alpha, cost_reduction=reduction, **kwargs).fit(X, Y)
        norms[name] = sum(float(p.detach().abs().sum()) for p in model.network_.parameters())
    assert norms["sum"] < norms["mean"] < norms["none"]
    assert norms["sum"] < 0.5 * norms["none"]


def test_cost_reports_both_terms(trained):
    X, Y = arm_data(100, seed=8)
    cost = trained.cost(X, Y)
    assert set(cost) == {"error", "l1"}
    assert cost["error"] > 0 and cost["l1"] > 0
    normalised = (trained.predict(X) - Y) / trained.y_std_
    assert cost["error"] == pytest.approx(np.mean(normalised**2), rel=1e-3)


def test_threads_setting_is_restored_after_training():
    before = torch.get_num_threads()
    X, Y = arm_data(16, seed=9)
    FeedForwardRegressor(hidden=8, epochs=1, threads=1, progress=False).fit(X, Y)
    assert torch.get_num_threads() == before


# ----------------------------------------------------------------------------- bad input
def test_predict_rejects_wrong_width_and_nan(trained):
    X, _ = arm_data(4, seed=10)
    with pytest.raises(RegressionInputError, match=r"rig 'arm': expected inputs of shape \(M, 6\)"):
        trained.predict(X[:, :5])
    X[1, 4] = np.nan
    with pytest.raises(RegressionInputError, match=r"first at row 1, column 4"):
        trained.predict(X)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        ({"hidden": 0}, "hidden must be >= 1"),
        ({"alpha": -0.1}, "alpha must be >= 0"),
        ({"learning_rate": 0.0}, "learning_rate must be > 0"),
        ({"cost_reduction": "max"}, "cost_reduction must be 'mean' or 'sum'"),
    ],
)
def test_bad_hyper_parameters_are_named(params, message):
    X, Y = arm_data(8, seed=11)
    with pytest.raises(ValueError, match=message):
        FeedForwardRegressor(**FAST, **params).fit(X, Y)


# ----------------------------------------------------------------------------- save / load
def test_save_load_round_trip(trained, tmp_path):
    trained.save(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nn.json", "nn.npz"]
    loaded = FeedForwardRegressor.load(tmp_path, rig="arm")
    X, _ = arm_data(20, seed=12)
    np.testing.assert_array_equal(loaded.predict(X), trained.predict(X))
    assert loaded.get_params() == trained.get_params()
    assert loaded.loss_history_ == trained.loss_history_
    assert isinstance(load_regressor(tmp_path), FeedForwardRegressor)


def test_loading_for_another_rig_or_corrupt_files_fails(trained, tmp_path):
    trained.save(tmp_path)
    with pytest.raises(
        ModelMismatchError, match="fitted for rig 'arm', but it is used with rig 'biped'"
    ):
        FeedForwardRegressor.load(tmp_path, rig="biped")
    (tmp_path / "nn.npz").write_bytes(b"\x00" * 10)
    with pytest.raises(ModelFileError, match="do not match the hash"):
        FeedForwardRegressor.load(tmp_path)


def test_hydra_config_has_the_papers_defaults():
    from hydra import compose, initialize

    with initialize(config_path="../conf", version_base="1.3"):
        cfg = compose("config", overrides=["regressor=nn", "experiment=paper", "seed=4"])
    model = instantiate(cfg.regressor)
    assert isinstance(model, FeedForwardRegressor)
    assert (model.hidden, model.alpha, model.batch_size, model.epochs) == (2048, 0.1, 8, 20)
    assert model.seed == 4


def test_repr_names_the_parameters_a_log_line_shows():
    # the fit log prints these; a model that names none keeps scikit-learn's repr
    assert repr(FeedForwardRegressor(hidden=16, epochs=3)) == (
        "FeedForwardRegressor(hidden=16, alpha=0.1, batch_size=8, epochs=3)"
    )
    assert repr(GaussianProcessRegressor(n_points=None)) == (
        "GaussianProcessRegressor(kernel=MultiquadricKernel(length_scale=1.0), "
        "regularization=1e-05, n_points=None)"
    )
    assert repr(JointSpaceNetworkRegressor(n_local=5, epochs=4)) == (
        "JointSpaceNetworkRegressor(hidden=512, layers=2, draws=3000+5+3000, epochs=20+4)"
    )
    assert repr(LearnedJacobian(seed=2)) == "LearnedJacobian(seed=2)"
