"""The whole latent model (scaling → PCA → GPLVM → back) on a linear rig's smooth takes."""

from __future__ import annotations

import numpy as np
import pytest

from latent_rigs import LinearRig
from rigmap.latent import GPLVMSettings, LatentInputError, LatentModel


@pytest.fixture(scope="module")
def setting():
    rng = np.random.default_rng(5)
    A = rng.standard_normal((9, 6)) * np.array([0.5, 4.0, 1.0, 8.0, 2.0, 0.1])
    rig = LinearRig(A, used=[True] * 6)
    mix = rng.uniform(-1.0, 1.0, (2, 6))  # |controls| ≤ 2: inside [-3, 3], nothing clipped
    takes = []
    for phase in (0.0, 1.3, 2.1):  # three takes of one 2-D motion, 30 frames each
        s = np.linspace(0, 2.0, 30) + phase
        takes.append(np.stack([np.sin(s), np.cos(1.5 * s)], 1) @ mix)
    P = np.vstack(takes)
    segments = np.repeat(["take a", "take b", "take c"], 30)
    settings = GPLVMSettings(latent_dim=2, max_iter=120)
    model = LatentModel.fit(rig, P, segments, fps=24, variance=0.99, settings=settings)
    return rig, P, segments, model


def surface_rms(rig, P, R) -> tuple[float, float]:
    """RMS joint error of ``R`` against ``P`` and the RMS joint spread of ``P`` (cm)."""
    a, b = rig.evaluate(rig.expand_used(P)), rig.evaluate(rig.expand_used(R))
    return float(np.sqrt(((a - b) ** 2).mean())), float(a.std(axis=0).mean())


def test_training_latents_give_back_the_training_poses(setting):
    """On the joints: scaling lets PCA drop controls that barely move them (§4.2), so the
    controls themselves come back only as well as they matter."""
    rig, P, _, model = setting
    R = model.to_controls(model.latent)
    assert R.shape == P.shape
    error, spread = surface_rms(rig, P, R)
    assert error < 0.03 * spread
    assert (R >= rig.controls.lower).all() and (R <= rig.controls.upper).all()


def test_unscaled_model_gives_back_the_controls(setting):
    rig, P, segments, _ = setting
    settings = GPLVMSettings(latent_dim=2, max_iter=120)
    model = LatentModel.fit(rig, P, segments, fps=24, variance=0.99, settings=settings, scale=False)
    R = model.to_controls(model.latent)
    assert np.sqrt(((R - P) ** 2).mean()) < 0.03 * P.std()


def test_a_projected_training_pose_comes_back(setting):
    rig, P, _, model = setting
    rows = [4, 40, 77]
    back = model.to_controls(model.project(P[rows]))
    error, spread = surface_rms(rig, P[rows], back)
    assert error < 0.05 * spread


def test_bad_segments_and_nan_controls_are_clear_errors(setting):
    rig, P, segments, _ = setting
    short = segments.copy()
    short[:2] = "take d"
    with pytest.raises(LatentInputError, match="take d"):
        LatentModel.fit(rig, P, short, fps=24)
    bad = P.copy()
    bad[3, 5] = np.inf
    with pytest.raises(LatentInputError, match="frame 3, column 5"):
        LatentModel.fit(rig, bad, segments, fps=24)
