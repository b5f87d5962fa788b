"""Learned Jacobian (§4.3-4.4) on a planar three-link arm with an analytic Jacobian.

Positions (elbow, wrist, tip: 6 numbers) depend on three angles (radians); the
training Jacobians are finite differences, as the paper computes them on a
black-box rig, and the analytic Jacobian is the reference.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.regression import (
    GaussianProcessRegressor,
    LearnedJacobian,
    ModelMismatchError,
    RegressionInputError,
)

LENGTHS = np.array([1.0, 0.8, 0.5])
CONTROL_NAMES = ("shoulder.rz", "elbow.rz", "wrist.rz")


def arm_angles(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(-0.8, 0.8, n), rng.uniform(0.2, 1.4, n), rng.uniform(0.1, 1.0, n)]
    )


def arm_positions(angles: np.ndarray) -> np.ndarray:
    heading = np.cumsum(angles, axis=1)
    steps = np.stack([np.cos(heading), np.sin(heading)], axis=2) * LENGTHS[:, None]
    return np.cumsum(steps, axis=1).reshape(len(angles), -1)


def analytic_jacobian(angles: np.ndarray) -> np.ndarray:
    """``(N, 6, 3)``: d(point k)/d(angle j) = sum over links j..k of L_i (-sin h_i, cos h_i)."""
    heading = np.cumsum(angles, axis=1)
    tangent = np.stack([-np.sin(heading), np.cos(heading)], axis=2) * LENGTHS[:, None]
    J = np.zeros((len(angles), 3, 2, 3))
    for k in range(3):
        for j in range(k + 1):
            J[:, k, :, j] = tangent[:, j : k + 1].sum(axis=1)
    return J.reshape(len(angles), 6, 3)


def finite_difference_jacobian(angles: np.ndarray, step: float = 1e-6) -> np.ndarray:
    columns = []
    for j in range(angles.shape[1]):
        delta = np.zeros(angles.shape[1])
        delta[j] = step
        columns.append((arm_positions(angles + delta) - arm_positions(angles - delta)) / (2 * step))
    return np.stack(columns, axis=2)


def relative_error(A: np.ndarray, B: np.ndarray) -> float:
    return float(np.linalg.norm(A - B) / np.linalg.norm(B))


@pytest.fixture(scope="module")
def training():
    angles = arm_angles(150, seed=0)
    return arm_positions(angles), finite_difference_jacobian(angles), angles


@pytest.fixture(scope="module")
def learned(training):
    X, J, _ = training
    return LearnedJacobian(n_length_scales=13, seed=1).fit(
        X, J, rig_name="arm", control_names=CONTROL_NAMES
    )


def test_finite_differences_agree_with_the_analytic_jacobian(training):
    _, J, angles = training
    assert relative_error(J, analytic_jacobian(angles)) < 1e-8


def test_close_to_the_finite_difference_jacobian_at_training_poses(learned, training):
    X, J, _ = training
    assert relative_error(learned.predict(X), J) < 1e-3


def test_generalises_to_unseen_poses(learned):
    angles = arm_angles(100, seed=2)
    predicted = learned.predict(arm_positions(angles))
    assert relative_error(predicted, analytic_jacobian(angles)) < 0.05
    assert 1e-4 <= learned.length_scale_ <= 1e2


def test_learned_at_the_gpr_support_points():
    """The paper's route: Jacobians at the inverse mapping's subsampled poses."""
    angles = arm_angles(300, seed=3)
    X = arm_positions(angles)
    gpr = GaussianProcessRegressor(n_points=60, n_length_scales=9).fit(X, angles)
    support_angles = angles[gpr.support_indices_]
    J = finite_difference_jacobian(support_angles)
    model = LearnedJacobian(kernel=gpr.kernel_, search_length_scale=False).fit(
        gpr.support_points(), J
    )
    assert model.length_scale_ == gpr.length_scale_
    assert relative_error(model.predict(gpr.support_points()), J) < 1e-3
    held_out = arm_angles(50, seed=4)
    assert relative_error(model.predict(arm_positions(held_out)), analytic_jacobian(held_out)) < 0.1


def test_shapes(learned, training):
    X = training[0]
    assert learned.predict(X[:7]).shape == (7, 6, 3)
    assert learned.predict(X[0]).shape == (6, 3)
    np.testing.assert_allclose(learned.predict(X[0]), learned.predict(X[:1])[0])


def test_bad_input_is_named(learned, training):
    X, J, _ = training
    with pytest.raises(RegressionInputError, match=r"expected inputs of shape \(M, 6\)"):
        learned.predict(X[:, :3])
    with pytest.raises(RegressionInputError, match=r"expected jacobians of shape \(150, R, C\)"):
        LearnedJacobian().fit(X, J.reshape(150, -1))
    J_bad = J.copy()
    J_bad[4, 1, 2] = np.nan
    with pytest.raises(RegressionInputError, match="jacobians contain NaN"):
        LearnedJacobian().fit(X, J_bad)


def test_save_load_round_trip_and_rig_check(learned, training, tmp_path):
    learned.save(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "learned_jacobian.json",
        "learned_jacobian.npz",
    ]
    loaded = LearnedJacobian.load(tmp_path, rig="arm")
    X = training[0][:20]
    np.testing.assert_array_equal(loaded.predict(X), learned.predict(X))
    assert loaded.fingerprint_.control_names == CONTROL_NAMES
    with pytest.raises(ModelMismatchError, match="fitted for rig 'arm'"):
        LearnedJacobian.load(tmp_path, rig="quadruped")
