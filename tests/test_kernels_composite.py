"""Summed and scaled kernels (as GPyTorch's ``+`` and ``ScaleKernel``) on real numbers."""

from __future__ import annotations

import numpy as np
import pytest
from hydra.utils import instantiate

from rigmap.regression import (
    GaussianKernel,
    GaussianProcessRegressor,
    LinearKernel,
    MultiquadricKernel,
    ScaleKernel,
    SumKernel,
    kernel_from_dict,
)
from rigmap.regression.length_scale_search import length_scale_cv_errors


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(3)
    return rng.normal(size=(7, 4)), rng.normal(size=(5, 4))


def test_a_sum_kernel_is_the_sum_of_the_gram_matrices(points):
    A, B = points
    parts = (MultiquadricKernel(0.7), GaussianKernel(1.3), LinearKernel(2.0, offset=0.5))
    total = parts[0] + parts[1] + parts[2]
    assert isinstance(total, SumKernel) and total.kernels == parts  # nested sums flatten
    np.testing.assert_allclose(total(A, B), sum(k(A, B) for k in parts), rtol=1e-14)
    np.testing.assert_allclose(total.diag(A), np.diag(total(A)), rtol=1e-12)
    columns = total.columns(A)
    for i in range(len(A)):
        np.testing.assert_allclose(columns(i), total(A)[:, i], rtol=1e-10, atol=1e-12)
    # the line search's reusable statistic gives the same Gram matrix
    np.testing.assert_allclose(total.from_statistic(total.statistic(A, B)), total(A, B))


def test_a_scaled_kernel_is_c_times_the_gram_matrix(points):
    A, B = points
    base = MultiquadricKernel(0.4)
    scaled = 2.5 * base
    assert isinstance(scaled, ScaleKernel) and scaled == base * 2.5
    np.testing.assert_allclose(scaled(A, B), 2.5 * base(A, B), rtol=1e-15)
    np.testing.assert_allclose(scaled.diag(A), 2.5 * base.diag(A), rtol=1e-15)
    np.testing.assert_allclose(scaled.columns(A)(3), 2.5 * base(A)[:, 3], rtol=1e-12)
    assert scaled.with_length_scale(2.0) == ScaleKernel(MultiquadricKernel(2.0), 2.5)
    assert scaled.search_range == base.search_range == (1e-4, 1e2)


def test_composites_round_trip_through_their_dicts_and_hydra():
    kernel = 3.0 * (MultiquadricKernel(0.5) + GaussianKernel(2.0))
    assert kernel_from_dict(kernel.to_dict()) == kernel
    config = {
        "_target_": "rigmap.regression.kernels.ScaleKernel",
        "outputscale": 3.0,
        "base_kernel": {
            "_target_": "rigmap.regression.kernels.SumKernel",
            "kernels": [
                {"_target_": "rigmap.regression.kernels.MultiquadricKernel", "length_scale": 0.5},
                {"_target_": "rigmap.regression.kernels.GaussianKernel", "length_scale": 2.0},
            ],
        },
    }
    assert instantiate(config, _convert_="all") == kernel


def test_a_sum_shares_one_length_scale_and_spans_its_parts_ranges():
    total = MultiquadricKernel(0.5) + GaussianKernel(2.0)
    assert total.length_scale == 0.5
    assert total.with_length_scale(3.0) == MultiquadricKernel(3.0) + GaussianKernel(3.0)
    assert total.search_range == (1e-4, 1e4)
    assert total.label == "multiquadric_plus_gaussian"
    assert (2.0 * total).label == "scaled_multiquadric_plus_gaussian"
    assert GaussianProcessRegressor(kernel=total).kernel_name == total.label
    with pytest.raises(ValueError, match="needs at least two kernels"):
        SumKernel((MultiquadricKernel(),))
    with pytest.raises(ValueError, match="outputscale must be a positive number"):
        ScaleKernel(MultiquadricKernel(), 0.0)


def arm(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A planar two-link arm: angles (rad) -> elbow and tip positions (unit-free)."""
    rng = np.random.default_rng(seed)
    angles = np.column_stack([rng.uniform(-0.8, 0.8, n), rng.uniform(0.2, 1.4, n)])
    heading = np.cumsum(angles, axis=1)
    steps = np.stack([np.cos(heading), np.sin(heading)], axis=2) * np.array([1.0, 0.8])[:, None]
    return np.cumsum(steps, axis=1).reshape(n, -1), angles


def test_a_scaled_kernel_in_a_gpr_is_the_same_fit_with_scaled_regularisation():
    """(cK + c·θ I)⁻¹ · cK* = (K + θ I)⁻¹ K*: the prediction must not change."""
    X, Y = arm(120, seed=0)
    X_test, _ = arm(30, seed=1)
    options = {"search_length_scale": False, "n_points": 60, "seed": 0}
    plain = GaussianProcessRegressor(kernel=MultiquadricKernel(0.3), regularization=1e-4, **options)
    scaled = GaussianProcessRegressor(
        kernel=4.0 * MultiquadricKernel(0.3), regularization=4e-4, **options
    )
    plain.fit(X, Y)
    scaled.fit(X, Y)
    np.testing.assert_array_equal(scaled.support_indices_, plain.support_indices_)
    np.testing.assert_allclose(scaled.predict(X_test), plain.predict(X_test), atol=1e-8)


def test_a_sum_kernel_gpr_searches_fits_and_predicts_the_arm(tmp_path):
    X, Y = arm(200, seed=0)
    X_test, Y_test = arm(50, seed=1)
    kernel = MultiquadricKernel() + LinearKernel()
    model = GaussianProcessRegressor(
        kernel=kernel, n_points=80, n_length_scales=5, cv_splits=2, seed=0
    ).fit(X, Y)
    assert isinstance(model.kernel_, SumKernel)
    assert model.length_scale_ in model.length_scales_
    cv = length_scale_cv_errors(
        (X - model.x_mean_) / model.x_std_,
        (Y - model.y_mean_) / model.y_std_,
        kernel,
        model.regularization,
        np.array([model.length_scale_]),
        2,
        np.random.default_rng(0),
    )
    assert np.isfinite(cv).all()
    error = float(np.sqrt(np.mean((model.predict(X_test) - Y_test) ** 2)))
    assert error < 0.02  # radians; the angles span about 1.6 rad
    model.save(tmp_path)
    loaded = GaussianProcessRegressor.load(tmp_path)
    assert loaded.kernel_ == model.kernel_
    np.testing.assert_array_equal(loaded.predict(X_test), model.predict(X_test))


def test_the_composite_kernel_config_builds_a_gpr_with_its_label():
    from hydra import compose, initialize

    with initialize(config_path="../conf", version_base="1.3"):
        cfg = compose("config", overrides=["regressor=gpr", "kernel=multiquadric_plus_linear"])
    model = instantiate(cfg.regressor, _convert_="all")
    assert model.kernel == MultiquadricKernel(1.0) + LinearKernel(1.0, offset=1.0)
    assert model.kernel_name == "multiquadric_plus_linear"
