"""The GPLVM of Bailey et al. 2016 §4.3 on small real problems: gradients, Eq 8, projection."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from rigmap.latent import GPLVM, GPLVMSettings, LatentInputError, segment_times
from rigmap.latent.gplvm import diffusion_log_kernel, dynamics_kernel


def two_takes(n_per: int = 20, d: int = 5, seed: int = 0):
    """Two segments of a smooth 2-D latent curve mapped nonlinearly to ``d`` outputs."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((4, d))
    rows = []
    for phase in (0.0, 0.7):
        s = np.linspace(0, 2.5, n_per) + phase
        latent = np.stack([np.cos(s), np.sin(2 * s)], axis=1)
        rows.append(np.tanh(np.hstack([latent, latent**2]) @ M))
    Y = np.vstack(rows)
    Y = Y - Y.mean(0)
    segments = np.repeat([0, 1], n_per)
    return Y, segments, segment_times(segments, 24.0)


def test_objective_gradient_matches_finite_differences():
    Y, seg, t = two_takes(n_per=6, d=3)
    model = GPLVM(GPLVMSettings(latent_dim=2))
    X0, h0 = model.setup(Y, seg, t)
    X0 = X0 + 0.05 * torch.randn(
        X0.shape, dtype=torch.float64, generator=torch.Generator().manual_seed(0)
    )
    X = X0.clone().requires_grad_(True)
    h = (h0 + torch.tensor([0.1, -0.2, 0.3], dtype=torch.float64)).requires_grad_(True)
    assert torch.autograd.gradcheck(model.objective, (X, h), eps=1e-6, atol=1e-5, rtol=1e-4)


def test_gradient_of_each_prior_alone_matches_finite_differences():
    Y, seg, t = two_takes(n_per=6, d=3)
    for settings in (
        GPLVMSettings(latent_dim=2, connectivity=False),
        GPLVMSettings(latent_dim=2, dynamics=False),
    ):
        model = GPLVM(settings)
        X0, h0 = model.setup(Y, seg, t)
        X = X0.clone().requires_grad_(True)
        h = h0.clone().requires_grad_(True)
        assert torch.autograd.gradcheck(model.objective, (X, h), eps=1e-6, atol=1e-5, rtol=1e-4)


def test_diffusion_kernel_matches_the_matrix_exponential():
    """Our positive-series exp(βH) agrees with torch's matrix_exp where both are accurate."""
    X = torch.as_tensor(np.random.default_rng(2).standard_normal((15, 3)))
    for beta in (0.3, 2.0, 5.0):
        log_k = diffusion_log_kernel(X, beta, power=4.0, eps=1e-3)
        d2 = torch.cdist(X, X) ** 2
        W = (d2 + 1e-6) ** -2.0 * (1 - torch.eye(15, dtype=X.dtype))
        r = W.sum(1).rsqrt()
        H = r[:, None] * W * r[None, :] - torch.eye(15, dtype=X.dtype)
        reference = torch.linalg.matrix_exp(beta * H)
        np.testing.assert_allclose(log_k.exp().numpy(), reference.numpy(), rtol=1e-9, atol=1e-13)
        assert torch.isfinite(log_k).all()


def test_dynamics_kernel_is_block_diagonal_per_segment():
    seg = np.array([0, 0, 0, 1, 1, 1])
    K = dynamics_kernel(segment_times(seg, 24.0), seg, GPLVMSettings()).numpy()
    assert np.all(K[:3, 3:] == 0) and np.all(K[3:, :3] == 0)
    np.testing.assert_allclose(K[:3, :3], K[3:, 3:])
    assert K[0, 1] > K[0, 2] > 0


@pytest.fixture(scope="module")
def fitted():
    Y, seg, t = two_takes()
    return Y, GPLVM(GPLVMSettings(latent_dim=2, max_iter=150)).fit(Y, seg, t)


def test_fit_lowers_the_objective_from_pca(fitted):
    _, model = fitted
    assert model.history[-1] < model.history[0] - 1.0
    assert 0 < model.iterations <= 150


def test_eq8_reproduces_the_training_outputs_at_their_latents(fitted):
    Y, model = fitted
    residual = model.mean(model.X) - Y
    noise = np.sqrt(model.white_variance)
    assert np.sqrt((residual**2).mean()) < 2 * noise
    assert np.sqrt((residual**2).mean()) < 0.05 * Y.std()
    # the predictive variance is small at the training points and the prior's far away
    assert model.variance(model.X).max() < 0.05 * model.kernel_variance
    far = model.X[:1] + 100.0
    assert model.variance(far)[0] == pytest.approx(model.kernel_variance, rel=1e-9)


def test_projection_returns_a_training_pose_to_its_latent(fitted):
    Y, model = fitted
    X = model.project(Y[[3, 11, 27]])
    scale = np.ptp(model.X, axis=0).max()
    assert np.abs(X - model.X[[3, 11, 27]]).max() < 0.02 * scale


def test_projection_finds_a_latent_between_training_points(fitted):
    """A pose generated at the midpoint of two frames is reproduced from the nearest training
    frame's latent. The map is many-to-one (§5.2: multi-modal), so the latent found may be
    another one with (almost) the same pose: the pose is what must come back."""
    _, model = fitted
    x_star = 0.5 * (model.X[[5, 25, 12]] + model.X[[6, 26, 13]])
    y_star = model.mean(x_star)
    X = model.project(y_star)
    assert np.abs(model.mean(X) - y_star).max() < 1e-3 * np.abs(y_star).max()
    start = model.project(model.mean(model.X[[5, 25, 12]]))  # the start is no answer here
    assert np.abs(model.mean(start) - y_star).max() > 1e-2 * np.abs(y_star).max()


def test_bad_training_sets_are_clear_errors():
    Y, seg, t = two_takes()
    seg = seg.copy()
    seg[:3] = 7  # a three-frame segment
    with pytest.raises(LatentInputError, match=r"fewer than 4 frames: \[\(7, 3\)\]"):
        GPLVM().fit(Y, seg, segment_times(seg, 24.0))
    named = np.array(["happy 0"] * 20 + ["happy 1"] * 17 + ["happy 2"] * 3, dtype=object)
    with pytest.raises(LatentInputError, match=r"fewer than 4 frames: \[\('happy 2', 3\)\]"):
        GPLVM().fit(Y, named, segment_times(named, 24.0))  # takes' names, as the library's
    Y_bad = Y.copy()
    Y_bad[9, 1] = np.nan
    with pytest.raises(LatentInputError, match="first at frame 9"):
        GPLVM().fit(Y_bad, np.repeat([0, 1], 20), t)
    with pytest.raises(LatentInputError, match="not fitted"):
        GPLVM().mean(np.zeros((1, 3)))


def test_the_closed_form_jacobian_matches_autograd(fitted):
    _, model = fitted
    x = torch.as_tensor(model.X[[2, 30]] + 0.1, dtype=torch.float64)
    _, J = model.mean_and_jacobian(x)
    for m in range(2):
        auto = torch.autograd.functional.jacobian(lambda v: model.mean_t(v[None])[0], x[m])
        np.testing.assert_allclose(J[m].numpy(), auto.numpy(), rtol=1e-9, atol=1e-12)


def test_connectivity_prior_pulls_a_distant_segment_closer():
    """ψ_C grows as a second take of a curve moves from far away into contact with the
    first (the paper's reason for it); it does not want them merged point on point: a
    near-duplicate pair dominates its ‖·‖⁻⁴ graph and starves the rest of the diffusion."""
    s = torch.linspace(0, 3, 30, dtype=torch.float64)
    chain = torch.stack([torch.cos(s), torch.sin(s)], 1)

    def prior(offset: float) -> float:
        X = torch.cat([chain, chain + torch.tensor([offset + 0.01, 0.0], dtype=torch.float64)])
        return float(diffusion_log_kernel(X, 2.0, 4.0, 1e-3).sum())

    values = [prior(offset) for offset in (3.0, 2.0, 1.0, 0.5)]
    assert all(a < b for a, b in itertools.pairwise(values))
    assert prior(0.0) < prior(0.5)
