"""Control scaling (Bailey et al. 2016 §4.1) and the PCA after it, on real rig evaluations."""

from __future__ import annotations

import numpy as np
import pytest

from latent_rigs import LinearRig
from rigmap.latent import LatentInputError, fit_control_scaling, fit_pca
from rigmap.latent.control_scaling import surface


@pytest.fixture
def linear_rig():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((12, 5)) * np.array([0.1, 1.0, 5.0, 20.0, 2.0])
    return LinearRig(A, used=[True, True, False, True, True])


def corpus(rig, n=200, seed=0):
    """Used-control values of different spreads, some pushed against the range's end."""
    rng = np.random.default_rng(seed)
    k = len(rig.controls.used_indices)
    P = rng.standard_normal((n, k)) * np.linspace(0.2, 1.5, k)
    P[:, 0] = np.clip(P[:, 0] + 2.8, -3.0, 3.0)  # a mean near the upper end: steps get clipped
    return P


def test_scaling_recovers_the_column_norms_of_a_linear_rig(linear_rig):
    P = corpus(linear_rig)
    scaling = fit_control_scaling(linear_rig, P)
    used = linear_rig.controls.used_indices
    expected = np.linalg.norm(linear_rig.A[:, used], axis=0)
    np.testing.assert_allclose(scaling.weights, expected, rtol=1e-10)
    assert scaling.names == ("c0", "c1", "c3", "c4")
    np.testing.assert_allclose(scaling.mean, P.mean(axis=0))


def test_scaled_steps_move_the_surface_by_one_unit(linear_rig):
    """Eq 1: a unit step of a scaled control moves the joints by one cm."""
    P = corpus(linear_rig)
    scaling = fit_control_scaling(linear_rig, P)
    base = scaling.scale(scaling.mean[None])
    for i in range(len(scaling.names)):
        step = base.copy()
        step[0, i] += 0.1
        moved = surface(linear_rig, linear_rig.expand_used(scaling.unscale(step, clamp=False)))
        rest = surface(linear_rig, linear_rig.expand_used(scaling.mean[None]))
        assert np.linalg.norm(moved - rest) == pytest.approx(0.1, rel=1e-9)


def test_scale_then_unscale_is_the_identity_and_unscale_clamps(linear_rig):
    P = corpus(linear_rig)
    scaling = fit_control_scaling(linear_rig, P)
    np.testing.assert_allclose(scaling.unscale(scaling.scale(P)), np.clip(P, -3, 3), atol=1e-12)
    far = scaling.scale(P[:1]) + 1e3
    back = scaling.unscale(far)
    assert (back <= 3.0).all() and (back >= -3.0).all()
    assert (scaling.unscale(far, clamp=False) > 3.0).all()


def test_a_mesh_rig_is_scaled_by_its_vertices():
    from rigmap.rigs import load

    face = load("face")
    Y = face.default_controls(1)
    assert surface(face, Y).shape == (1, face.n_vertices, 3)
    assert face.n_vertices > face.n_joints


def test_nan_controls_are_a_clear_error(linear_rig):
    P = corpus(linear_rig)
    P[7, 2] = np.nan
    with pytest.raises(LatentInputError, match="frame 7, column 2"):
        fit_control_scaling(linear_rig, P)
    with pytest.raises(LatentInputError, match=r"shape \(N, 4\)"):
        fit_control_scaling(linear_rig, P[:, :3])


def test_pca_keeps_at_least_the_variance_fraction(linear_rig):
    rng = np.random.default_rng(1)
    Z = rng.standard_normal((300, 10)) @ rng.standard_normal((10, 10))
    for fraction in (0.5, 0.85, 0.95):
        pca = fit_pca(Z, variance=fraction)
        kept = pca.explained_variance_ratio_.sum()
        assert kept >= fraction
        fewer = fit_pca(Z, n_components=pca.n_components_ - 1) if pca.n_components_ > 1 else None
        if fewer is not None:  # the fewest components that reach it
            assert fewer.explained_variance_ratio_.sum() < fraction
        centred = Z - Z.mean(0)
        rebuilt = pca.inverse_transform(pca.transform(Z)) - Z.mean(0)
        assert 1 - ((centred - rebuilt) ** 2).sum() / (centred**2).sum() == pytest.approx(kept)
    with pytest.raises(LatentInputError, match="variance fraction"):
        fit_pca(Z, variance=1.5)
