"""Refinement pulled toward the guess on a real CMU kick (the fastest frames of the walk)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigmap.animation.library import build_corpus
from rigmap.map import JointMap, tracks_from_bvh
from rigmap.map.clip import MapError, MapSettings, solve_controls
from rigmap.map.curves import largest_jumps, smooth, unwrap_rotations
from rigmap.map.partial import JointSubset, SubsetMapping
from rigmap.map.prior_refinement import PriorRig
from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.regression import GaussianProcessRegressor
from rigmap.regression.features import inverse_features
from rigmap.regression.kernels import MultiquadricKernel

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"
KICK = slice(735, 751)  # 120 fps frames where the right foot kicks up at ~10 m/s


@pytest.fixture(scope="module")
def kick(biped):
    Y = build_corpus(biped, "train", seed=0).values()
    pose = biped.pose(biped.expand_used(Y))
    X = inverse_features(pose.positions, pose.cog, pose.cog_rotation, n_joints=biped.n_joints,
                         where="biped corpus")  # fmt: skip
    retarget = JointMap.from_yaml(ROOT / "conf/retarget/cmu_biped.yaml")
    subset = JointSubset("cmu", "biped", tuple(retarget.joints), "pelvis", "thigh_l", "thigh_r")
    regressor = GaussianProcessRegressor(MultiquadricKernel(), n_points=250, n_length_scales=9,
                                         cv_splits=4, progress=False)  # fmt: skip
    mapping = SubsetMapping.fit(biped, subset, X, Y, regressor)
    targets = retarget.apply(biped, tracks_from_bvh(WALK))
    columns = [targets.joint_names.index(j) for j in subset.joints]
    return mapping, targets.positions[KICK][:, columns], Y.std(axis=0), np.median(Y, axis=0)


def test_prior_rows_are_the_weighted_controls(biped):
    view = WorldSubsetRig(biped, ["foot_l", "hand_r"])
    weights = np.linspace(0.0, 2.0, len(biped.used_controls))
    rig = PriorRig(view, weights)
    Y = biped.expand_used(np.random.default_rng(0).normal(0, 0.1, (3, len(weights))))
    out = rig.evaluate(Y)
    assert out.shape == (3, 2 + rig.n_prior, 3) and rig.n_prior == -(-len(weights) // 3)
    np.testing.assert_allclose(out[:, :2], view.evaluate(Y))
    flat = out[:, 2:].reshape(3, -1)
    np.testing.assert_allclose(flat[:, : len(weights)], Y[:, biped.controls.used_indices] * weights)
    assert not flat[:, len(weights) :].any()
    heavy = PriorRig(view, weights, joint_weights=[3.0, 1.0]).evaluate(Y)
    np.testing.assert_allclose(heavy[:, 0], 3.0 * out[:, 0])
    np.testing.assert_allclose(heavy[:, 1:], out[:, 1:])
    with pytest.raises(MapError, match="prior_weight"):
        MapSettings(prior_weight=-1.0)


def test_the_prior_calms_the_kick_and_keeps_the_joints_close(biped, kick):
    mapping, world, std, median = kick
    kinds = [biped.controls.kinds[i] for i in biped.controls.used_indices]
    view = WorldSubsetRig(biped, mapping.subset.joints)
    found = {}
    for weight in (0.0, 1.0):
        settings = MapSettings(refine_iterations=3, prior_weight=weight)
        Y = unwrap_rotations(
            solve_controls(biped, mapping, world, settings, std, median, {}), kinds
        )
        error = np.sqrt(((view.evaluate(biped.expand_used(Y)) - world) ** 2).sum(axis=2).mean())
        found[weight] = (largest_jumps(Y, std).max(), error)
        if weight == 1.0:  # MapSettings' default smoothing (1 frame) before key reduction
            calm = smooth(Y, MapSettings().smoothing_frames)
            calm_error = np.sqrt(((view.evaluate(biped.expand_used(calm)) - world) ** 2)
                                 .sum(axis=2).mean())  # fmt: skip
    guess = mapping.predict(world)
    guess_error = np.sqrt(((view.evaluate(biped.expand_used(guess)) - world) ** 2).sum(2).mean())
    (plain_jump, plain_error), (prior_jump, prior_error) = found[0.0], found[1.0]
    assert plain_jump > 8.0  # plain Eq. 13 swings hips.rz by ~11 training std in one frame
    assert prior_jump < 0.7 * plain_jump
    assert prior_error < plain_error + 1.5 < guess_error  # cm: still far closer than the guess
    assert largest_jumps(calm, std).max() < 5.0 < prior_jump
    assert calm_error < prior_error + 0.5
