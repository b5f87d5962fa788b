"""Inverse-mapping inputs: joint positions plus the COG placement."""

from __future__ import annotations

import numpy as np
import pytest

from rig_poses import random_used_controls
from rigmap.regression.features import feature_names, inverse_features, split_features
from rigmap.rigs import RigInputError


def test_features_round_trip_and_name_every_column(biped):
    pose = biped.pose(random_used_controls(biped, 4, seed=2))
    X = inverse_features(*pose, n_joints=biped.n_joints, where="test")
    names = feature_names(biped.joint_names)
    assert X.shape == (4, 3 * biped.n_joints + 12) == (4, len(names))
    assert names[0] == "pelvis.x" and names[-1] == "cog_rot.22"
    positions, cog, rotation = split_features(X, biped.n_joints)
    np.testing.assert_array_equal(positions, pose.positions)
    np.testing.assert_array_equal(cog, pose.cog)
    np.testing.assert_array_equal(rotation, pose.cog_rotation)
    # the COG translation shows only in the placement columns
    Y = random_used_controls(biped, 1, seed=2)
    Y[0, biped.controls.index("root.tx")] += 25.0
    moved = inverse_features(*biped.pose(Y), n_joints=biped.n_joints, where="test")
    changed = np.flatnonzero(np.abs(moved[0] - X[0]) > 1e-9)
    assert [names[i] for i in changed] == ["cog.x"]


def test_bad_features_input(biped):
    pose = biped.pose(biped.default_controls(2))
    with pytest.raises(RigInputError, match=r"expected cog \(2, 3\) and cog_rotation \(2, 3, 3\)"):
        inverse_features(pose.positions, pose.cog[:1], pose.cog_rotation, n_joints=73, where="t")
    bad = pose.cog.copy()
    bad[1, 2] = np.nan
    with pytest.raises(RigInputError, match="cog or cog_rotation contains NaN"):
        inverse_features(pose.positions, bad, pose.cog_rotation, n_joints=73, where="t")
    with pytest.raises(RigInputError, match=r"\(N, 73, 3\)"):
        inverse_features(pose.positions[:, :5], pose.cog, pose.cog_rotation, n_joints=73, where="t")
