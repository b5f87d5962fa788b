"""Root channels found on the rig, and inputs/targets that ignore where the character is."""

from __future__ import annotations

import numpy as np
import pytest

from rig_poses import random_used_controls
from rigmap.refine import jacobian
from rigmap.regression import GaussianProcessRegressor, LearnedJacobian
from rigmap.regression.features import inverse_features
from rigmap.regression.mapping import InverseMapping, JacobianMapping
from rigmap.regression.placement import (
    Placement,
    find_placement,
    heading,
    turn_matrix,
)
from rigmap.rigs import RigInputError, load


def pose_rows(rig, Y_full):
    pose = rig.pose(Y_full)
    return inverse_features(
        pose.positions, pose.cog, pose.cog_rotation, n_joints=rig.n_joints, where="test"
    )


@pytest.fixture(scope="module")
def quadruped_placement(quadruped):
    probes = random_used_controls(quadruped, 3, seed=1)[:, quadruped.controls.used_indices]
    return find_placement(quadruped, probes)


def moved(rig, placement, Y_full, dx, dz, turn):
    """The same poses walked ``dx``/``dz`` cm and turned ``turn`` rad by the root."""
    used = rig.controls.used_indices
    out = Y_full.copy()
    gx, gz = placement.ground
    out[:, used[gx.index]] += dx
    out[:, used[gz.index]] += dz
    out[:, used[placement.turn.index]] += turn
    return out


def test_heading_adds_a_turn_about_up_whatever_the_tilt():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(20, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    R = np.stack(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    ).transpose(2, 0, 1)
    turned = turn_matrix(np.full(20, 0.4)) @ R
    difference = (heading(turned) - heading(R) - 0.4 + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(difference, 0.0, atol=1e-12)
    np.testing.assert_allclose(heading(turn_matrix(np.array([0.3, -2.0]))), [0.3, -2.0])


def test_root_channels_are_found_and_child_offsets_are_not(quadruped_placement):
    placement = quadruped_placement
    assert [c.name for c in placement.ground] == ["root.tx", "root.tz"]
    assert placement.turn.name == "root.ry"
    for channel in [*placement.ground, placement.turn]:
        assert channel.gain == pytest.approx(1.0, abs=1e-9)
    # the root turns about its own origin
    np.testing.assert_allclose(placement.pivot_rest, 0.0, atol=1e-6)
    # cog.tx moves the body over planted IK paws: not a rigid move, so regressed
    assert "cog.tx" not in [c.name for c in placement.channels]


def test_inputs_and_targets_ignore_where_the_character_stands(quadruped, quadruped_placement):
    placement = quadruped_placement
    Y = random_used_controls(quadruped, 6, seed=2)
    Y_far = moved(quadruped, placement, Y, dx=140.0, dz=-75.0, turn=-1.9)
    X, X_far = pose_rows(quadruped, Y), pose_rows(quadruped, Y_far)
    assert np.abs(X - X_far).max() > 10.0  # the world inputs do change (cm)
    np.testing.assert_allclose(placement.inputs(X_far), placement.inputs(X), atol=1e-9)
    used = quadruped.controls.used_indices
    np.testing.assert_allclose(
        placement.targets(Y_far[:, used], X_far), placement.targets(Y[:, used], X), atol=1e-9
    )
    # and back: the root channels come out of the COG placement exactly
    targets = placement.targets(Y_far[:, used], X_far)
    np.testing.assert_allclose(placement.controls(targets, X_far), Y_far[:, used], atol=1e-9)


def test_jacobians_in_the_input_frame_do_not_depend_on_the_heading(quadruped, quadruped_placement):
    placement = quadruped_placement
    Y = random_used_controls(quadruped, 2, seed=3)
    Y_turned = moved(quadruped, placement, Y, dx=30.0, dz=10.0, turn=1.2)
    J, J_turned = jacobian(quadruped, Y), jacobian(quadruped, Y_turned)
    X, X_turned = pose_rows(quadruped, Y), pose_rows(quadruped, Y_turned)
    assert np.abs(J - J_turned).max() > 0.1
    local = placement.jacobians_to_inputs_frame(J, X)
    np.testing.assert_allclose(
        placement.jacobians_to_inputs_frame(J_turned, X_turned), local, atol=1e-5
    )
    np.testing.assert_allclose(placement.jacobians_to_world(local, X), J, atol=1e-12)


def test_a_learned_jacobian_turned_on_its_entries_is_the_dense_turn(quadruped, quadruped_placement):
    """JacobianMapping.predict turns only the predicted entries' (joint, column) triples."""
    placement = quadruped_placement
    Y = random_used_controls(quadruped, 12, seed=5)
    Y_turned = moved(quadruped, placement, Y, dx=-20.0, dz=40.0, turn=2.1)
    X = pose_rows(quadruped, np.concatenate([Y, Y_turned]))
    J = jacobian(quadruped, np.concatenate([Y, Y_turned]), colouring=None)
    learned = LearnedJacobian(n_length_scales=5, seed=0).fit(
        placement.inputs(X), placement.jacobians_to_inputs_frame(J, X)
    )
    mapping = JacobianMapping(learned, placement)
    assert learned.pattern().mean() < 0.5  # a sparse pattern: the compact path is exercised
    dense = placement.jacobians_to_world(learned.predict(placement.inputs(X)), X)
    np.testing.assert_allclose(mapping.predict(X), dense, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mapping.predict(X[3]), dense[3], rtol=0, atol=1e-12)


def test_a_rig_without_root_channels_keeps_the_pose_row():
    face = load("face")
    probes = random_used_controls(face, 2, seed=4)[:, face.controls.used_indices]
    placement = find_placement(face, probes)
    assert placement.ground is None and placement.turn is None
    X = pose_rows(face, random_used_controls(face, 3, seed=5))
    np.testing.assert_array_equal(placement.inputs(X), X)
    assert placement.input_width == placement.pose_width == X.shape[1]


def test_mapping_predicts_root_channels_for_a_character_far_away(quadruped, quadruped_placement):
    """Trained near the origin facing +Z, the mapping places a pose 3 m away, turned."""
    placement = quadruped_placement
    used = quadruped.controls.used_indices
    Y = random_used_controls(quadruped, 40, seed=6, spread=0.15)
    Y[:, [used[c.index] for c in placement.channels]] = 0.0  # all at the origin, facing +Z
    mapping = InverseMapping(GaussianProcessRegressor(search_length_scale=False), placement)
    mapping.fit(pose_rows(quadruped, Y), Y[:, used])
    Y_far = moved(quadruped, placement, Y[:5], dx=300.0, dz=250.0, turn=2.5)
    predicted = mapping.predict(pose_rows(quadruped, Y_far))
    np.testing.assert_allclose(predicted, Y_far[:, used], atol=1e-4)


def test_wrong_pose_rows_are_refused_with_the_expected_shape(quadruped_placement):
    with pytest.raises(RigInputError, match=r"expected pose rows of shape \(N, 240\)"):
        quadruped_placement.inputs(np.zeros((2, 239)))
    with pytest.raises(RigInputError, match=r"expected controls of shape \(2, 218\)"):
        quadruped_placement.targets(np.zeros((2, 5)), np.zeros((2, 240)))


def test_placement_survives_a_round_trip_through_json(quadruped_placement):
    again = Placement.from_dict(quadruped_placement.to_dict())
    assert again == quadruped_placement
    with pytest.raises(ValueError, match="expected format"):
        Placement.from_dict({"format": "something else"})
