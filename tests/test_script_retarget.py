"""The "Maya script" baseline: rotation maths, exactness at rest, accuracy on plausible poses."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch

from rig_poses import random_used_controls
from rigmap.retarget import (
    NoRetargetScriptError,
    euler_to_matrix,
    matrix_to_euler,
    script_retarget,
)
from rigmap.retarget.orient import (
    best_rotation,
    principal_rotation,
    rotate,
    rotation_between,
    two_axis_aim,
    unit,
)
from rigmap.rigs import RigInputError, load
from rigmap.rigs.engine.transforms import ROTATION_ORDERS, euler_matrix

RIGS = ("quadruped", "biped")
# joints the IK controls are snapped to: they must land on their targets
IK_ENDS = {
    "quadruped": ("wrist_l", "wrist_r", "hind_paw_l", "hind_paw_r"),
    "biped": ("hand_l", "hand_r", "foot_l", "foot_r"),
}
# joints carried by the IK ends (the ball of each foot or front paw)
BALLS = {
    "quadruped": ("front_paw_l", "front_paw_r"),
    "biped": ("ball_l", "ball_r"),
}


def _joint_error(rig, result, pose) -> np.ndarray:
    """Per-frame, per-joint squared distance (cm²) of the script's pose from the target."""
    reached = rig.evaluate(rig.expand_used(result.Y_used))
    return ((reached - pose.positions) ** 2).sum(-1)


# --- rotation maths -------------------------------------------------------------


@pytest.mark.parametrize("order", ROTATION_ORDERS)
def test_matrix_to_euler_round_trips_with_the_engine(order):
    rng = np.random.default_rng(0)
    angles = rng.uniform(-np.pi, np.pi, size=(200, 3))
    middle = "xyz".index(order[1])
    angles[:, middle] = rng.uniform(-1.5, 1.5, size=200)  # the principal range of the middle angle
    R = euler_matrix(torch.from_numpy(angles), order).numpy()
    recovered = matrix_to_euler(R, order)
    np.testing.assert_allclose(recovered, angles, atol=1e-10)
    # the other orders give other angles for the same matrix (the order matters)
    other = next(o for o in ROTATION_ORDERS if o != order)
    assert np.abs(matrix_to_euler(R, other) - angles).max() > 0.1


@pytest.mark.parametrize("order", ROTATION_ORDERS)
def test_matrix_to_euler_in_gimbal_lock_still_rebuilds_the_matrix(order):
    rng = np.random.default_rng(1)
    angles = rng.uniform(-np.pi, np.pi, size=(20, 3))
    angles[:, "xyz".index(order[1])] = np.where(rng.uniform(size=20) < 0.5, -np.pi / 2, np.pi / 2)
    R = euler_to_matrix(angles, order)
    np.testing.assert_allclose(euler_to_matrix(matrix_to_euler(R, order), order), R, atol=1e-12)


def test_matrix_to_euler_rejects_an_unknown_order():
    with pytest.raises(ValueError, match="rotation order must be one of"):
        matrix_to_euler(np.eye(3)[None], "xxy")


def test_rotation_between_turns_one_direction_onto_another_even_opposite():
    rng = np.random.default_rng(2)
    a = unit(rng.normal(size=(50, 3)))
    b = unit(rng.normal(size=(50, 3)))
    b[0] = -a[0]  # antiparallel: any half turn will do
    R = rotation_between(a, b)
    np.testing.assert_allclose(rotate(R, a), b, atol=1e-12)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )


def test_best_rotation_recovers_a_rotation_from_carried_points():
    rng = np.random.default_rng(3)
    truth = euler_to_matrix(rng.uniform(-np.pi, np.pi, size=(30, 3)))
    rest = rng.normal(size=(4, 3))
    moved = np.einsum("nij,kj->nki", truth, rest)
    np.testing.assert_allclose(best_rotation(rest, moved), truth, atol=1e-10)


@pytest.mark.parametrize(("inner", "outer"), [("x", "y"), ("x", "z"), ("y", "z")])
def test_two_axis_aim_reaches_reachable_directions(inner, outer):
    rng = np.random.default_rng(4)
    d0 = unit(rng.normal(size=(100, 3)))
    truth = rng.uniform(-1.0, 1.0, size=(100, 2))
    R = principal_rotation(truth[:, 1], outer) @ principal_rotation(truth[:, 0], inner)
    d1 = rotate(R, d0)
    a_inner, a_outer = two_axis_aim(d0, d1, inner, outer)
    aimed = rotate(principal_rotation(a_outer, outer) @ principal_rotation(a_inner, inner), d0)
    np.testing.assert_allclose(aimed, d1, atol=1e-9)


# --- the scripts on their rigs ---------------------------------------------------


@pytest.mark.parametrize("name", RIGS)
def test_rest_pose_gives_back_the_default_controls(name):
    rig = load(name)
    pose = rig.pose(rig.default_controls(3))
    result = script_retarget(rig, pose.positions, pose.cog, pose.cog_rotation)
    assert result.Y_used.shape == (3, len(rig.used_controls))
    defaults = rig.controls.defaults[rig.controls.used_indices]
    np.testing.assert_allclose(
        result.Y_used, np.broadcast_to(defaults, result.Y_used.shape), atol=1e-9
    )
    assert _joint_error(rig, result, pose).max() < 1e-18
    # one rest evaluation, then three read-backs of every frame
    assert result.rig_evaluations == 1 + 3 * 3


@pytest.mark.parametrize("name", RIGS)
def test_plausible_poses_are_close_and_the_ik_ends_land(name):
    rig = load(name)
    Y = random_used_controls(rig, 50, seed=11, spread=0.15)
    pose = rig.pose(Y)
    result = script_retarget(rig, pose)
    assert np.isfinite(result.Y_used).all()
    error = _joint_error(rig, result, pose)  # (N, J) cm²
    script_mse = error.mean() / 3
    default_mse = ((rig.evaluate(rig.default_controls(50)) - pose.positions) ** 2).mean()
    assert script_mse < 0.01 * default_mse
    ends = [rig.joint_names.index(j) for j in IK_ENDS[name]]
    assert np.sqrt(error[:, ends]).max() < 1e-3  # cm
    balls = [rig.joint_names.index(j) for j in BALLS[name]]
    assert np.sqrt(error[:, balls]).mean() < 1.0  # cm; IK/FK-blended targets bend the foot


@pytest.mark.parametrize("name", RIGS)
def test_pure_ik_poses_are_reproduced_except_what_the_controls_cannot_express(name):
    """With the limbs fully in IK and the head following the neck, only the
    quadruped's toe side-curl (its toes turn about x only) is out of reach."""
    rig = load(name)
    Y = random_used_controls(rig, 20, seed=5, spread=0.15)
    for i, control in enumerate(rig.control_names):
        if control.endswith((".ik_fk", ".follow")):
            Y[:, i] = 1.0
    pose = rig.pose(Y)
    error = _joint_error(rig, script_retarget(rig, pose), pose)
    toes = [i for i, j in enumerate(rig.joint_names) if "_toe_" in j]
    eyes = [i for i, j in enumerate(rig.joint_names) if j.startswith("eye_end")]
    rest = np.setdiff1d(np.arange(rig.n_joints), toes + eyes)
    assert error[:, rest].max() < 1e-12
    # the pupils sit 1.2-1.5 cm from the eye: the aim depth barely shows
    assert error[:, eyes].max() < 1e-2
    if toes:
        assert error[:, toes].max() < 1.0


def test_frames_in_chunks_give_the_same_controls(biped):
    pose = biped.pose(random_used_controls(biped, 9, seed=2, spread=0.15))
    whole = script_retarget(biped, pose)
    chunked = script_retarget(biped, pose, chunk=4)
    np.testing.assert_allclose(chunked.Y_used, whole.Y_used, atol=1e-10)
    assert chunked.rig_evaluations == 3 + 3 * 9  # one rest pose per chunk


# --- bad input ----------------------------------------------------------------


def test_wrong_joint_count_is_refused(quadruped):
    pose = quadruped.pose(quadruped.default_controls(2))
    with pytest.raises(RigInputError, match=r"expected joint positions of shape \(N, 76, 3\)"):
        script_retarget(quadruped, pose.positions[:, :-1], pose.cog, pose.cog_rotation)


def test_nan_positions_are_refused(biped):
    pose = biped.pose(biped.default_controls(2))
    positions = pose.positions.copy()
    positions[1, 4, 0] = np.nan
    with pytest.raises(RigInputError, match=r"NaN or infinity .*row 1, joint 4"):
        script_retarget(biped, positions, pose.cog, pose.cog_rotation)


def test_bad_cog_placement_is_refused(biped):
    pose = biped.pose(biped.default_controls(2))
    with pytest.raises(RigInputError, match="needs the COG placement"):
        script_retarget(biped, pose.positions)
    with pytest.raises(RigInputError, match=r"expected cog \(2, 3\)"):
        script_retarget(biped, pose.positions, pose.cog[:1], pose.cog_rotation)
    cog = pose.cog.copy()
    cog[0, 1] = np.inf
    with pytest.raises(RigInputError, match="cog or cog_rotation contains NaN"):
        script_retarget(biped, pose.positions, cog, pose.cog_rotation)
    sheared = pose.cog_rotation.copy()
    sheared[1, 0, 1] = 0.3
    with pytest.raises(RigInputError, match="frame 1 is not"):
        script_retarget(biped, pose.positions, pose.cog, sheared)


def test_a_rig_without_a_script_is_refused():
    with pytest.raises(NoRetargetScriptError, match="no retarget script for rig 'rigify_wolf'"):
        script_retarget(SimpleNamespace(name="rigify_wolf"), np.zeros((1, 3, 3)))


def test_eyes_look_the_right_way_when_their_lines_meet_behind_the_head(biped):
    """Wide poses: some frames' look lines meet behind the eyes; the aim must stay in front."""
    Y = random_used_controls(biped, 50, seed=0, spread=0.3)
    pose = biped.pose(Y)
    error = _joint_error(biped, script_retarget(biped, pose), pose)
    pupils = [biped.joint_names.index(j) for j in ("eye_end_l", "eye_end_r")]
    # cm; the pupils are 1.2 cm from the eyes, so an eye looking backwards misses by ~2.4 cm,
    # while the head's frame estimate leaves a few millimetres on the widest poses
    assert np.sqrt(error[:, pupils]).max() < 0.5
