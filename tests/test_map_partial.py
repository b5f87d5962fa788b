"""Partial-input mappings (Figs 5, 6): controls from a joint subset around a virtual COG."""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.map.partial import JointSubset, SubsetError, SubsetMapping
from rigmap.regression import GaussianProcessRegressor
from rigmap.regression.features import inverse_features
from rigmap.regression.kernels import MultiquadricKernel
from rigmap.regression.placement import turn_matrix
from rigmap.rigs import RigInputError

FEET = {"joints": ["foot_l", "foot_r", "toe_l", "toe_r"], "origin": "foot_l",
        "left": "foot_l", "right": "foot_r"}  # fmt: skip
EFFECTORS = {"joints": ["pelvis", "spine_chest", "head", "hand_l", "hand_r", "foot_l", "foot_r"],
             "origin": "pelvis", "left": "foot_l", "right": "foot_r"}  # fmt: skip


OFFSET = np.array([300.0, 0.0, 120.0])


def random_poses(rig, n, seed, spread=0.15):
    """Used controls near the rest pose, their full pose rows, and world joints."""
    rng = np.random.default_rng(seed)
    used = rig.controls.used_indices
    low, high = rig.controls.lower[used], rig.controls.upper[used]
    Y = rig.controls.defaults[used] + rng.normal(0, spread, (n, len(used))) * (high - low) / 2
    Y = np.clip(Y, low, high)
    pose = rig.pose(rig.expand_used(Y))
    X = inverse_features(pose.positions, pose.cog, pose.cog_rotation, n_joints=rig.n_joints,
                         where="random poses")  # fmt: skip
    world = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
    return Y, X, world


def gpr(points):
    return GaussianProcessRegressor(MultiquadricKernel(), n_points=points, n_length_scales=5,
                                    cv_splits=2, progress=False)  # fmt: skip


@pytest.fixture(scope="module")
def effector_mapping(biped):
    Y, X, _ = random_poses(biped, 400, seed=0)
    subset = JointSubset.from_mapping(EFFECTORS, name="effectors", rig=biped)
    return SubsetMapping.fit(biped, subset, X, Y, gpr(400))


def test_virtual_cog_rows_ignore_where_the_subset_stands(biped):
    subset = JointSubset.from_mapping(EFFECTORS, name="effectors", rig=biped)
    _, X, world = random_poses(biped, 5, seed=1)
    sub = subset.world_from_pose_rows(X, biped)
    np.testing.assert_allclose(sub, world[:, subset.columns(biped)], atol=1e-12)
    turned = np.einsum("ab,njb->nja", turn_matrix(np.array(1.3)), sub) + np.array(
        [250.0, 0.0, -80.0]
    )
    rows, moved = subset.pose_rows(sub), subset.pose_rows(turned)
    k = 3 * len(subset.joints)
    relative = rows[:, :k].reshape(5, -1, 3)
    np.testing.assert_allclose(
        np.einsum("ab,njb->nja", turn_matrix(np.array(1.3)), relative),
        moved[:, :k].reshape(5, -1, 3),
        atol=1e-9,
    )
    heading_change = subset.heading(turned) - subset.heading(sub)
    np.testing.assert_allclose(np.angle(np.exp(1j * heading_change)), 1.3, atol=1e-9)


def test_effector_mapping_fits_its_training_poses(biped, effector_mapping):
    _, _, world = random_poses(biped, 400, seed=0)
    subset = effector_mapping.subset
    predicted = effector_mapping.predict(world[:, subset.columns(biped)])
    replay = biped.pose(biped.expand_used(predicted))
    replay_world = np.asarray(replay.positions) + np.asarray(replay.cog)[:, None, :]
    error = ((replay_world - world)[:, subset.columns(biped)] ** 2).mean()
    assert error < 1e-3  # GPR interpolates its 400 training poses (cm^2)


def test_effector_mapping_follows_a_turned_and_moved_character(biped, effector_mapping):
    _, _, world = random_poses(biped, 30, seed=7)
    subset = effector_mapping.subset
    sub = world[:, subset.columns(biped)]
    turn = turn_matrix(np.array(2.2))
    moved = np.einsum("ab,njb->nja", turn, sub) + OFFSET
    here = biped.pose(biped.expand_used(effector_mapping.predict(sub)))
    there = biped.pose(biped.expand_used(effector_mapping.predict(moved)))
    here_world = np.asarray(here.positions) + np.asarray(here.cog)[:, None, :]
    there_world = np.asarray(there.positions) + np.asarray(there.cog)[:, None, :]
    expected = np.einsum("ab,njb->nja", turn, here_world) + OFFSET
    np.testing.assert_allclose(there_world, expected, atol=1e-4)


def test_held_out_poses_beat_the_mean_predictor(biped, effector_mapping):
    Y_train, _, _ = random_poses(biped, 400, seed=0)
    _, _, world = random_poses(biped, 60, seed=11)
    columns = effector_mapping.subset.columns(biped)
    predicted = effector_mapping.predict(world[:, columns])
    replay = biped.pose(biped.expand_used(predicted))
    replay_world = np.asarray(replay.positions) + np.asarray(replay.cog)[:, None, :]
    mean = biped.pose(biped.expand_used(np.tile(Y_train.mean(axis=0), (60, 1))))
    mean_world = np.asarray(mean.positions) + np.asarray(mean.cog)[:, None, :]
    given = ((replay_world - world)[:, columns] ** 2).mean()
    baseline = ((mean_world - world)[:, columns] ** 2).mean()
    assert given < 0.25 * baseline


def test_saved_mapping_loads_and_predicts_the_same(biped, effector_mapping, tmp_path):
    _, _, world = random_poses(biped, 8, seed=3)
    sub = world[:, effector_mapping.subset.columns(biped)]
    effector_mapping.save(tmp_path / "effectors")
    loaded = SubsetMapping.load(tmp_path / "effectors", biped)
    assert loaded.subset == effector_mapping.subset
    np.testing.assert_array_equal(loaded.predict(sub), effector_mapping.predict(sub))
    with pytest.raises(SubsetError, match="is for rig 'biped', not 'quadruped'"):
        from rigmap.rigs import load

        SubsetMapping.load(tmp_path / "effectors", load("quadruped"))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"origin": "neck_1"}, "frame joints ['neck_1'] must be among"),
        ({"joints": ["foot_l", "foot_r", "wing"]}, "has no joints ['wing']"),
        ({"right": "foot_l"}, "left and right are both 'foot_l'"),
        ({"left": None}, "frame joints [None]"),
    ],
)
def test_bad_subsets_are_named(biped, change, message):
    import re

    data = {**FEET, **change}
    with pytest.raises(SubsetError, match=re.escape(message)):
        JointSubset.from_mapping(data, name="feet", rig=biped)


def test_feet_only_input_checks_its_positions(biped):
    subset = JointSubset.from_mapping(FEET, name="feet", rig=biped)
    with pytest.raises(SubsetError, match=r"expected positions \(N, 4, 3\)"):
        subset.pose_rows(np.zeros((3, 5, 3)))
    bad = np.ones((2, 4, 3))
    bad[1, 2, 0] = np.nan
    with pytest.raises(SubsetError, match="joint 'toe_l' is not finite at frame 1"):
        subset.pose_rows(bad)


def test_posing_from_seven_effectors_reaches_them(biped, effector_mapping, tmp_path):
    import json

    from rigmap.map.clip import MapSettings
    from rigmap.map.effectors import EffectorError, pose_from_effectors, read_effector_targets

    Y_train, _, _ = random_poses(biped, 400, seed=0)
    _, _, world = random_poses(biped, 2, seed=21)
    joints = effector_mapping.subset.joints
    targets = world[:, effector_mapping.subset.columns(biped)]
    frames = [{j: targets[f, k].tolist() for k, j in enumerate(joints)} for f in range(2)]
    (tmp_path / "drag.json").write_text(json.dumps({"rig": "biped", "frames": frames}))
    read = read_effector_targets(tmp_path / "drag.json", joints)
    np.testing.assert_array_equal(read, targets)
    std, median = Y_train.std(axis=0), np.median(Y_train, axis=0)
    guess = pose_from_effectors(biped, effector_mapping, read, MapSettings(refine_iterations=0),
                                control_std=std, hold_values=median)  # fmt: skip
    plain = MapSettings(refine_iterations=3, prior_weight=0.0)  # reach the effectors exactly
    refined = pose_from_effectors(biped, effector_mapping, read, plain,
                                  control_std=std, hold_values=median)  # fmt: skip
    assert refined[0].shape == (2, biped.n_controls)
    assert refined[1].max() < 1.0 and refined[1].mean() < 0.5 * guess[1].mean() + 1e-9
    frames[1].pop("head")
    (tmp_path / "gap.json").write_text(json.dumps({"rig": "biped", "frames": frames}))
    with pytest.raises(EffectorError, match=r"gap\.json: frame 1: .* missing \['head'\]"):
        read_effector_targets(tmp_path / "gap.json", joints)
    (tmp_path / "bad.json").write_text('{"targets": {"pelvis": [0, 1]}}')
    with pytest.raises(EffectorError, match=r"bad\.json"):
        read_effector_targets(tmp_path / "bad.json", ("pelvis",))


def test_interactive_posing_follows_a_drag(biped, effector_mapping):
    """A drag: the effectors of a pose moved toward another's in 8 small steps. Each pose
    costs its four rig calls, lands closer than the mapping's guess, and the last pose of
    the drag reaches its targets about as well as the batch refinement does."""
    from rigmap.map.clip import MapSettings
    from rigmap.map.effectors import pose_from_effectors
    from rigmap.map.interactive_pose import STEP_LENGTHS, InteractivePoser

    Y_train, _, _ = random_poses(biped, 400, seed=0)
    _, _, world = random_poses(biped, 2, seed=33)
    ends = world[:, effector_mapping.subset.columns(biped)]
    drag = [ends[0] + t * (ends[1] - ends[0]) for t in np.linspace(0, 1, 9)]
    std, median = Y_train.std(axis=0), np.median(Y_train, axis=0)
    carried = InteractivePoser(biped, effector_mapping, control_std=std, hold_values=median,
                               carry_jacobian=True)  # fmt: skip
    carried_results = [carried(target) for target in drag]
    poser = InteractivePoser(biped, effector_mapping, control_std=std, hold_values=median,
                             carry_jacobian=False)  # fmt: skip
    results = [poser(target) for target in drag]
    guesses = pose_from_effectors(biped, effector_mapping, np.array(drag),
                                  MapSettings(refine_iterations=0), control_std=std,
                                  hold_values=median)[1]  # fmt: skip
    distances = np.array([r.distance_cm for r in results])
    assert (distances <= guesses + 1e-9).all() and distances.mean() < 0.5 * guesses.mean()
    carried_distances = np.array([r.distance_cm for r in carried_results])
    assert (carried_distances <= guesses + 1e-9).all()
    assert sum(r.rig_evaluations for r in carried_results) < sum(r.rig_evaluations for r in results)
    # only the controls that move the effectors are differenced: not the fingers or eyes
    moving = {biped.used_controls[k] for k in poser.columns}
    assert (
        "leg_l_ik.tx" in moving
        and "arm_r_ik.tz" in moving
        and not any(n.startswith(("index_", "eye_")) for n in moving)
    )
    first, rest = results[0].rig_evaluations, [r.rig_evaluations for r in results[1:]]
    assert first == 1 + len(poser.columns) + 1 + poser.steps * len(STEP_LENGTHS)
    assert max(rest) <= 2 + len(poser.columns) + 1 + poser.steps * len(STEP_LENGTHS)
    reached = biped.pose(results[-1].controls[None])
    at = (np.asarray(reached.positions) + np.asarray(reached.cog)[:, None])[0]
    np.testing.assert_allclose(
        np.sqrt(((at[effector_mapping.subset.columns(biped)] - drag[-1]) ** 2).sum(1).mean()),
        distances[-1], atol=1e-6)  # fmt: skip
    for result in (results[-1], carried_results[-1]):  # every joint, from the chosen call
        posed = biped.pose(result.controls[None])
        world_joints = (np.asarray(posed.positions) + np.asarray(posed.cog)[:, None])[0]
        np.testing.assert_allclose(result.joints, world_joints, atol=1e-9)
    batch = pose_from_effectors(biped, effector_mapping, drag[-1][None],
                                MapSettings(refine_iterations=3, prior_weight=0.0),
                                control_std=std, hold_values=median)[1]  # fmt: skip
    assert distances[-1] < max(2 * batch[0], 0.5)
    with pytest.raises(RigInputError, match=r"interactive posing on 'biped'.*\(7, 3\)"):
        poser(drag[0][:3])
