"""The constraint-based script baseline on Rigify rigs."""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.rigs.blender import constraint_retarget
from rigmap.rigs.blender.rigify import build_rigify_human

pytestmark = [
    pytest.mark.blender,
]


@pytest.fixture(scope="module")
def human():
    rig = build_rigify_human(workers=1)
    yield rig
    rig.close()


def body_poses(rig, n, rng):
    """Poses reachable by the baseline's own controls: torso placement and IK hands/feet."""
    c = rig.controls.index
    Y = rig.default_controls(n)
    for name in ("torso.tx", "torso.ty", "torso.tz"):
        Y[:, c(name)] = rng.uniform(-10, 10, n)  # cm
    Y[:, c("torso.rz")] = rng.uniform(-0.5, 0.5, n)  # rad
    for side in "LR":
        for axis in "xyz":
            Y[:, c(f"hand_ik.{side}.t{axis}")] = rng.uniform(-8, 8, n)
            Y[:, c(f"foot_ik.{side}.t{axis}")] = rng.uniform(-5, 5, n)
    return Y


def test_retarget_puts_hands_feet_and_cog_on_their_targets(human):
    Y = body_poses(human, 4, np.random.default_rng(5))
    target = human.pose(Y)
    solved = constraint_retarget(human, target)
    assert solved.shape == Y.shape
    got = human.pose(solved)
    np.testing.assert_allclose(got.cog, target.cog, atol=1e-3)  # cm
    np.testing.assert_allclose(got.cog_rotation, target.cog_rotation, atol=1e-5)
    for name in ("DEF-hand.L", "DEF-hand.R", "DEF-foot.L", "DEF-foot.R"):
        j = human.joint_names.index(name)
        error = np.linalg.norm(got.positions[:, j] - target.positions[:, j], axis=1)
        assert error.max() < 0.1, (name, error)  # cm
    c = human.controls.index
    np.testing.assert_allclose(solved[:, c("torso.rz")], Y[:, c("torso.rz")], atol=1e-4)
    untouched = c("forearm_fk.L.rx")  # not in the mapping: stays at its default
    assert (solved[:, untouched] == human.controls.defaults[untouched]).all()


def test_rig_is_left_as_it_was(human):
    Y = human.default_controls(1)
    before = human.pose(Y)
    constraint_retarget(human, human.pose(body_poses(human, 2, np.random.default_rng(6))))
    after = human.pose(Y)
    assert np.array_equal(before.positions, after.positions)


def test_mapping_errors_name_the_entry(human):
    pose = human.pose(human.default_controls(1))
    with pytest.raises(ValueError, match="not in"):
        constraint_retarget(human, pose, mapping=[{"bone": "torso", "type": "IK", "target": "cog"}])
    with pytest.raises(ValueError, match="neither 'cog' nor a joint"):
        constraint_retarget(
            human, pose, mapping=[{"bone": "torso", "type": "COPY_LOCATION", "target": "DEF-nope"}]
        )
    with pytest.raises(ValueError, match="lacks"):
        constraint_retarget(human, pose, mapping=[{"bone": "torso"}])
