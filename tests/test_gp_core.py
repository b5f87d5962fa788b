"""The GP core (rigmap.gp) against direct formulas, and its three users on small problems.

Every check compares with a computation that does not go through the core: loops over
pairs, ``numpy.linalg.solve`` / ``slogdet``, SciPy's multivariate normal density,
finite differences.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from scipy.stats import multivariate_normal

from rigmap.edits.gp import SharedGP
from rigmap.gp.distances import expanded_squared_distances, squared_distances
from rigmap.gp.kernels import (
    GaussianKernel,
    LinearKernel,
    MultiquadricKernel,
    PolynomialKernel,
    rbf,
    rbf_d_log_lengthscale,
    rbf_gram,
    rbf_input_gradient,
)
from rigmap.gp.likelihood import negative_log_marginal_likelihood
from rigmap.gp.solve import (
    add_noise,
    cholesky,
    cholesky_solve,
    log_det,
    solve_lower,
    solve_lower_transposed,
    solve_regularized,
)
from rigmap.latent.gplvm import GPLVM, GPLVMSettings
from rigmap.latent.particle import LatentField
from rigmap.regression import GaussianProcessRegressor


@pytest.fixture
def points():
    rng = np.random.default_rng(7)
    return rng.standard_normal((9, 3)) + 4.0, rng.standard_normal((5, 3)) + 4.0


def _pairwise(f, A, B):
    return np.array([[f(a, b) for b in B] for a in A])


def test_distances_match_differences_and_torch_matches_numpy(points):
    A, B = points
    direct = _pairwise(lambda a, b: float(((a - b) ** 2).sum()), A, B)
    np.testing.assert_allclose(squared_distances(A, B), direct, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(expanded_squared_distances(A, B), direct, rtol=1e-10, atol=1e-10)
    assert np.all(np.diag(squared_distances(A, A)) == 0.0)
    as_torch = expanded_squared_distances(torch.as_tensor(A), torch.as_tensor(B))
    # torch and numpy multiply with different BLAS: equal to round-off of |a|² ~ 50
    np.testing.assert_allclose(as_torch.numpy(), expanded_squared_distances(A, B), atol=1e-12)


def test_kernel_values_match_their_formulas(points):
    A, B = points
    sq = _pairwise(lambda a, b: float(((a - b) ** 2).sum()), A, B)
    dot = A @ B.T
    cases = {
        MultiquadricKernel(0.3): np.sqrt(sq + 0.09),
        GaussianKernel(1.7): np.exp(-sq / (2 * 1.7**2)),
        LinearKernel(2.0, offset=0.5): dot / 4.0 + 0.5,
        PolynomialKernel(2.0, offset=1.0, degree=3): (dot / 4.0 + 1.0) ** 3,
        MultiquadricKernel(0.3) + GaussianKernel(0.3): np.sqrt(sq + 0.09)
        + np.exp(-sq / (2 * 0.09)),
        2.5 * GaussianKernel(1.7): 2.5 * np.exp(-sq / (2 * 1.7**2)),
    }
    for kernel, expected in cases.items():
        np.testing.assert_allclose(kernel(A, B), expected, rtol=1e-10, err_msg=kernel.label)
        np.testing.assert_allclose(kernel.diag(A), np.diag(kernel(A)), rtol=1e-12)
    np.testing.assert_allclose(rbf_gram(A, B, 1.3, 0.8), 1.3 * np.exp(-sq / 1.6), rtol=1e-10)
    torch_gram = rbf_gram(torch.as_tensor(A), torch.as_tensor(B), 1.3, 0.8)
    np.testing.assert_allclose(torch_gram.numpy(), rbf_gram(A, B, 1.3, 0.8), rtol=1e-12)


def test_rbf_gradients_match_finite_differences(points):
    A, B = points
    variance, ls2, h = 1.3, 0.8, 1e-6
    K = rbf_gram(A, B, variance, ls2)
    analytic = rbf_input_gradient(K, A[:, None, :] - B[None], ls2)  # (M, N, q)
    for j in range(A.shape[1]):
        step = np.zeros(A.shape[1])
        step[j] = h
        numeric = (rbf_gram(A + step, B, variance, ls2) - rbf_gram(A - step, B, variance, ls2)) / (
            2 * h
        )
        np.testing.assert_allclose(analytic[..., j], numeric, rtol=1e-6, atol=1e-9)
    sq = expanded_squared_distances(A, B)
    log_l, dl = 0.5 * np.log(ls2), 1e-6
    numeric = (
        rbf(sq, variance, np.exp(2 * (log_l + dl))) - rbf(sq, variance, np.exp(2 * (log_l - dl)))
    ) / (2 * dl)
    np.testing.assert_allclose(rbf_d_log_lengthscale(K, sq, ls2), numeric, rtol=1e-6, atol=1e-9)
    # the torch evaluation's autograd gradient is the same derivative
    At = torch.as_tensor(A).requires_grad_(True)
    rbf_gram(At, torch.as_tensor(B), variance, ls2).sum().backward()
    np.testing.assert_allclose(At.grad.numpy(), analytic.sum(1), rtol=1e-10, atol=1e-12)


def _spd(n: int, seed: int) -> np.ndarray:
    M = np.random.default_rng(seed).standard_normal((n, n))
    return M @ M.T + n * np.eye(n)


def test_solves_match_numpy_linalg_solve():
    K, B = _spd(12, 1), np.random.default_rng(2).standard_normal((12, 3))
    expected = np.linalg.solve(K + 0.25 * np.eye(12), B)
    L = cholesky(add_noise(K.copy(), 0.2, 0.05))
    np.testing.assert_allclose(cholesky_solve(L, B), expected, rtol=1e-10)
    Lt = cholesky(add_noise(torch.as_tensor(K), 0.2, 0.05))
    np.testing.assert_allclose(cholesky_solve(Lt, torch.as_tensor(B)).numpy(), expected, rtol=1e-10)
    lower = np.tril(L)
    np.testing.assert_allclose(solve_lower(L, B), np.linalg.solve(lower, B), rtol=1e-10)
    np.testing.assert_allclose(
        solve_lower_transposed(L, B), np.linalg.solve(lower.T, B), rtol=1e-10
    )
    np.testing.assert_allclose(
        solve_lower(Lt, torch.as_tensor(B)).numpy(), np.linalg.solve(lower, B), rtol=1e-10
    )
    sign, logdet = np.linalg.slogdet(K + 0.25 * np.eye(12))
    assert sign > 0 and log_det(L) == pytest.approx(logdet, rel=1e-12)
    # the LU solve, for indefinite matrices (a multiquadric Gram matrix)
    X = np.random.default_rng(3).standard_normal((15, 2))
    Kmq = MultiquadricKernel(0.5)(X)
    solution = solve_regularized(Kmq, B[:, :2].repeat(2, 0)[:15], 1e-3)
    expected = np.linalg.solve(Kmq + 1e-3 * np.eye(15), B[:, :2].repeat(2, 0)[:15])
    assert solution.solver == "lu"
    np.testing.assert_allclose(solution.weights, expected, rtol=1e-8)


def test_marginal_likelihood_matches_the_gaussian_density():
    K, Y = _spd(10, 4), np.random.default_rng(5).standard_normal((10, 3))
    direct = -sum(multivariate_normal(np.zeros(10), K).logpdf(Y[:, j]) for j in range(3))
    L = cholesky(K.copy())
    value = negative_log_marginal_likelihood(Y, cholesky_solve(L, Y), L)
    assert value == pytest.approx(direct, rel=1e-12)
    Kt, Yt = torch.as_tensor(K), torch.as_tensor(Y)
    Lt = cholesky(Kt)
    assert float(negative_log_marginal_likelihood(Yt, cholesky_solve(Lt, Yt), Lt)) == (
        pytest.approx(direct, rel=1e-12)
    )


@pytest.fixture
def regression_data():
    rng = np.random.default_rng(3)
    X = rng.standard_normal((60, 3)) + 5.0
    Y = np.c_[np.sin(X[:, 0]) + X[:, 1] ** 2, np.cos(X[:, 2])]
    return X, Y, rng.standard_normal((8, 3)) + 5.0


@pytest.mark.parametrize("kernel", [MultiquadricKernel(), GaussianKernel()], ids=lambda k: k.name)
def test_gpr_predicts_the_dense_formula(regression_data, kernel):
    """Eq. 6 on the chosen support points, the Gram matrices built pair by pair."""
    X, Y, Xt = regression_data
    model = GaussianProcessRegressor(
        kernel=kernel, n_points=30, n_length_scales=5, cv_splits=2, n_farthest=3, seed=1
    ).fit(X, Y)
    length = model.length_scale_
    if kernel.name == "multiquadric":

        def k(a, b):
            return np.sqrt(((a - b) ** 2).sum() + length**2)
    else:

        def k(a, b):
            return np.exp(-((a - b) ** 2).sum() / (2 * length**2))

    x_mean, x_std = X.mean(0), X.std(0)
    y_mean, y_std = Y.mean(0), Y.std(0)
    support = model.support_indices_
    Xs, Ys = (X[support] - x_mean) / x_std, (Y[support] - y_mean) / y_std
    W = np.linalg.solve(_pairwise(k, Xs, Xs) + 1e-5 * np.eye(len(Xs)), Ys)
    expected = _pairwise(k, (Xt - x_mean) / x_std, Xs) @ W * y_std + y_mean
    np.testing.assert_allclose(model.predict(Xt), expected, rtol=1e-6, atol=1e-8)


def test_shared_gp_predicts_and_scores_the_dense_formula(regression_data):
    X, Y, Xt = regression_data
    Y = Y + 0.1 * np.random.default_rng(11).standard_normal(Y.shape)  # noise a GP can fit
    gp = SharedGP().fit(X, Y)
    Xn, Xtn = (X - gp.x_mean_) / gp.x_std_, (Xt - gp.x_mean_) / gp.x_std_
    s2, l2, n2 = gp.signal_**2, gp.length_scale_**2, gp.noise_**2

    def k(a, b):
        return s2 * np.exp(-((a - b) ** 2).sum() / (2 * l2))

    K = _pairwise(k, Xn, Xn) + (n2 + 1e-10) * np.eye(len(X))
    Ks = _pairwise(k, Xtn, Xn)
    Yc = Y - Y.mean(0)
    prediction = gp.predict(Xt)
    np.testing.assert_allclose(
        prediction.mean, Ks @ np.linalg.solve(K, Yc) + Y.mean(0), rtol=1e-7, atol=1e-9
    )
    variance = s2 + n2 - np.einsum("ij,ji->i", Ks, np.linalg.solve(K, Ks.T))
    np.testing.assert_allclose(prediction.variance, np.maximum(variance, n2), rtol=1e-6)
    density = sum(multivariate_normal(np.zeros(len(X)), K).logpdf(Yc[:, j]) for j in range(2))
    assert gp.log_marginal_likelihood_ == pytest.approx(density, rel=1e-9)
    # the objective's analytic gradient (lower-triangle sums) against central differences
    theta, h = np.log([0.7, 1.3, 0.2]), 1e-6
    gradient = gp._objective(theta)[1]
    numeric = [
        (gp._objective(theta + h * e)[0] - gp._objective(theta - h * e)[0]) / (2 * h)
        for e in np.eye(3)
    ]
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-6)


def _small_gplvm(connectivity: bool) -> tuple[GPLVM, np.ndarray]:
    t = np.arange(40) / 24.0
    Y = np.c_[np.sin(3 * t), np.cos(2 * t), np.sin(5 * t) * t]
    settings = GPLVMSettings(latent_dim=2, max_iter=10, connectivity=connectivity)
    return GPLVM(settings).fit(Y, np.repeat([0, 1], 20), t), Y


def test_gplvm_mean_variance_and_likelihood_match_the_dense_formula():
    g, Y = _small_gplvm(connectivity=True)
    X, s2, l2, w = g.X, g.kernel_variance, g.lengthscale2, g.white_variance

    def k(a, b):
        return s2 * np.exp(-((a - b) ** 2).sum() / (2 * l2))

    K = _pairwise(k, X, X) + w * np.eye(len(X))
    Z = X[::6] + 0.05
    Ks = _pairwise(k, Z, X)
    np.testing.assert_allclose(g.mean(Z), Ks @ np.linalg.solve(K, Y), rtol=1e-7, atol=1e-9)
    variance = s2 - np.einsum("ij,ji->i", Ks, np.linalg.solve(K, Ks.T))
    np.testing.assert_allclose(g.variance(Z), np.maximum(variance, 0.0), rtol=1e-6, atol=1e-12)
    # with both priors off the objective is the GP's negative log likelihood alone
    bare = GPLVM(GPLVMSettings(latent_dim=2, dynamics=False, connectivity=False))
    bare.setup(Y, np.repeat([0, 1], 20), np.arange(40) / 24.0)
    value = float(bare.objective(torch.as_tensor(X), g.log_hyper))
    Kb = _pairwise(k, X, X) + (np.exp(float(g.log_hyper[2])) + 1e-6 * bare.data_variance) * np.eye(
        len(X)
    )
    density = sum(multivariate_normal(np.zeros(len(X)), Kb).logpdf(Y[:, j]) for j in range(3))
    assert value == pytest.approx(-density, rel=1e-9)


def test_gplvm_objective_gradient_matches_finite_differences():
    g, _ = _small_gplvm(connectivity=True)
    X = torch.as_tensor(g.X).clone().requires_grad_(True)
    h = g.log_hyper.clone().requires_grad_(True)
    g.objective(X, h).backward()
    step = 1e-6
    for i, j in [(0, 0), (7, 1), (33, 0)]:
        plus, minus = g.X.copy(), g.X.copy()
        plus[i, j] += step
        minus[i, j] -= step
        numeric = (
            float(g.objective(torch.as_tensor(plus), g.log_hyper))
            - float(g.objective(torch.as_tensor(minus), g.log_hyper))
        ) / (2 * step)
        assert float(X.grad[i, j]) == pytest.approx(numeric, rel=1e-5, abs=1e-6)
    for i in range(3):
        plus, minus = g.log_hyper.clone(), g.log_hyper.clone()
        plus[i] += step
        minus[i] -= step
        Xt = torch.as_tensor(g.X)
        numeric = (float(g.objective(Xt, plus)) - float(g.objective(Xt, minus))) / (2 * step)
        assert float(h.grad[i]) == pytest.approx(numeric, rel=1e-5, abs=1e-6)


def test_particle_field_confidence_gradient_matches_finite_differences():
    g, _ = _small_gplvm(connectivity=False)
    model = SimpleNamespace(
        gplvm=g,
        pca=SimpleNamespace(components_=np.eye(3), mean_=np.zeros(3)),
        scaling=SimpleNamespace(
            weights=np.ones(3), mean=np.zeros(3), lower=-9 * np.ones(3), upper=9 * np.ones(3)
        ),
    )
    field = LatentField(model)
    x = g.X[5] + 0.1
    c, gradient = field.confidence_and_gradient(x)
    assert c == pytest.approx(field.confidence(x), rel=1e-12)
    assert c == pytest.approx(1.0 - g.variance(x[None])[0] / g.kernel_variance, rel=1e-8)
    numeric = [
        (field.confidence(x + 1e-6 * e) - field.confidence(x - 1e-6 * e)) / 2e-6 for e in np.eye(2)
    ]
    np.testing.assert_allclose(gradient, numeric, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(field.controls(x, clamp=False), g.mean(x[None])[0], rtol=1e-10)
