"""Rigify rigs evaluated by real Blender workers (the CI smoke test of the Blender backend).

Skipped only when the Blender worker environment is not installed (`make blender`).
The first run generates the Rigify rigs into the cache (~10 s each); later runs reuse them.
"""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from rigmap.rigs import RigInputError
from rigmap.rigs.blender.rigify import build_rigify_human, build_rigify_wolf

pytestmark = [
    pytest.mark.blender,
]


@pytest.fixture(scope="module")
def human():
    rig = build_rigify_human(workers=2, chunk_rows=4)
    yield rig
    rig.close()


def random_used(rig, n, rng, spread=0.15):
    """Control vectors with the used controls moved around their defaults."""
    Y = rig.default_controls(n)
    used = rig.controls.used_indices
    half_range = (rig.controls.upper[used] - rig.controls.lower[used]) / 2
    Y[:, used] += rng.uniform(-1, 1, size=(n, len(used))) * spread * half_range
    return np.clip(Y, rig.controls.lower, rig.controls.upper)


def joint(rig, name):
    return rig.joint_names.index(name)


def gone(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_human_lists_rigify_controls_and_body_joints(human):
    stats = human.stats
    summary = human.controls.summary()
    assert 200 <= stats["control_bones"] <= 240  # Rigify's ~220 control bones
    assert 1600 <= stats["transform_channels"] <= 1800
    assert stats["custom_properties"] >= 40  # IK/FK, stretch, follow, parent switches...
    assert 180 <= summary["used"] <= 220
    assert human.n_joints >= 45 and not any("lip" in j or "brow" in j for j in human.joint_names)
    assert set(summary["by_kind"]) == {"rotate", "translate", "scale", "scalar"}
    for name in ("hand_ik.L.tx", "upper_arm_parent.L.IK_FK", "torso.rz"):
        assert human.controls[name].used
    assert human.controls["upper_arm_parent.L.IK_FK"].kind == "scalar"
    assert len(human.parents) == human.n_joints and human.parents.min() == -1


def dead_used_controls(rig) -> list[str]:
    """Used controls that move neither a joint nor the COG from a pose where both IK and FK
    count (IK/FK at 0.5). IK stretch is left out: it only acts on out-of-reach targets."""
    used = [i for i in rig.controls.used_indices if not rig.control_names[i].endswith("IK_Stretch")]
    base = random_used(rig, 1, np.random.default_rng(7), spread=0.1)
    for i, name in enumerate(rig.control_names):
        if name.endswith(".IK_FK"):
            base[0, i] = 0.5
    Y = np.repeat(base, len(used) + 1, axis=0)
    for k, i in enumerate(used):
        Y[k + 1, i] += 2.0 if rig.controls.kinds[i] == "translate" else 0.1  # cm / rad / factor
    pose = rig.pose(Y)
    moved = np.abs(pose.positions[1:] - pose.positions[0]).max(axis=(1, 2))
    moved = np.maximum(moved, np.abs(pose.cog[1:] - pose.cog[0]).max(axis=1))
    return [rig.control_names[i] for k, i in enumerate(used) if moved[k] < 1e-4]


def test_every_used_control_moves_the_joints_or_the_cog(human):
    assert not dead_used_controls(human)


def test_rest_pose_is_symmetric_and_cog_is_the_torso(human):
    pose = human.pose(human.default_controls(1))
    X = pose.positions[0]
    for left in [j for j in human.joint_names if j.endswith(".L")]:
        mirrored = X[joint(human, left[:-2] + ".R")] * [-1, 1, 1]
        np.testing.assert_allclose(X[joint(human, left)], mirrored, atol=0.05)  # cm
    assert 90.0 < pose.cog[0, 1] < 130.0  # hip height of a 1.8 m human, in cm, Y up
    head, foot, toe = (X[joint(human, n)] for n in ("DEF-spine.006", "DEF-foot.L", "DEF-toe.L"))
    assert head[1] - foot[1] > 140.0 and toe[2] > foot[2] + 5.0  # standing up, facing +Z
    assert X[joint(human, "DEF-hand.L"), 0] > 50.0  # +X is the character's left
    R = pose.cog_rotation[0]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-6)


def test_ik_hand_control_moves_the_hand_and_nothing_on_the_other_side(human):
    Y = human.default_controls(2)
    Y[1, human.controls.index("hand_ik.L.tx")] += 10.0
    X = human.evaluate(Y)
    moved = np.linalg.norm(X[1] - X[0], axis=1)
    assert moved[joint(human, "DEF-hand.L")] == pytest.approx(10.0, abs=0.05)  # cm
    assert moved[joint(human, "DEF-hand.R")] < 1e-4
    assert moved[joint(human, "DEF-foot.L")] < 1e-4


def test_ik_fk_switch_decides_whether_fk_controls_count(human):
    c = human.controls.index
    Y = human.default_controls(5)
    Y[1, c("forearm_fk.L.rx")] = 0.8
    Y[2:, c("upper_arm_parent.L.IK_FK")] = 1.0
    Y[3:, c("forearm_fk.L.rx")] = 0.8
    Y[4, c("upper_arm_parent.L.IK_FK")] = 1.7  # beyond the property's hard max of 1
    X = human.evaluate(Y)
    hand = joint(human, "DEF-hand.L")
    assert np.array_equal(X[1], X[0])  # IK mode: the FK forearm does nothing
    assert np.linalg.norm(X[3, hand] - X[2, hand]) > 5.0  # FK mode: it bends the arm (cm)
    assert np.array_equal(X[4], X[3])  # clamped like Blender clamps keyframes


def test_batches_give_the_same_numbers_as_single_rows(human):
    Y = random_used(human, 6, np.random.default_rng(1))
    batch = human.pose(Y)
    for row in (0, 5):
        single = human.pose(Y[row])
        assert np.array_equal(single.positions, batch.positions[row])
        assert np.array_equal(single.cog, batch.cog[row])
    assert np.isfinite(batch.positions).all()
    assert np.ptp(batch.positions, axis=0).max() > 1.0  # the poses really differ


def test_killing_a_worker_mid_batch_retries_with_identical_result(human):
    Y = random_used(human, 24, np.random.default_rng(2))
    reference = human.pose(Y)
    pool = human.pool
    victim = pool.pids()[0]
    restarts = pool.restarts
    killed = []

    def kill_once(_rows):
        if not killed:
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)

    again = human.evaluate_with_progress(Y, kill_once)
    assert killed and gone(victim) and pool.restarts > restarts
    assert np.array_equal(again.positions, reference.positions)
    assert np.array_equal(again.cog_rotation, reference.cog_rotation)
    pids = pool.pids()
    human.close()
    assert all(gone(pid) for pid in pids), "a Blender worker outlived close()"


def test_pruned_evaluation_equals_the_full_rig(human):
    Y = random_used(human, 3, np.random.default_rng(4))
    with build_rigify_human(workers=1, prune=False) as full:
        assert full.stats["pruned_bones"] == 0 < human.stats["pruned_bones"]
        np.testing.assert_array_equal(full.evaluate(Y), human.evaluate(Y))


def test_controls_set_in_a_worker_read_back_in_control_units(human):
    y = random_used(human, 1, np.random.default_rng(8))[0]
    y[human.controls.index("upper_arm_parent.L.IK_FK")] = 3.0  # clamped to its hard max, 1
    human.pool.call("set_controls", arrays={"controls": y})
    _, out = human.pool.call("read_controls")
    back = out["controls"]
    live = ~np.isnan(back)  # NaN: on a bone pruned away (cannot move the joints)
    assert live[human.controls.used_indices].all() and 0 < (~live).sum() < human.n_controls
    expected = y.copy()
    expected[human.controls.index("upper_arm_parent.L.IK_FK")] = 1.0
    np.testing.assert_allclose(back[live], expected[live], rtol=1e-6, atol=1e-5)


def test_torch_in_torch_out_and_bad_input_is_refused(human):
    torch = pytest.importorskip("torch")
    Y = torch.as_tensor(human.default_controls(1), dtype=torch.float32)
    X = human.evaluate(Y)
    assert isinstance(X, torch.Tensor) and X.dtype == torch.float32
    assert human.differentiable is False
    with pytest.raises(RigInputError, match=r"expected controls of shape \(N, 1"):
        human.evaluate(np.zeros((1, 5)))
    bad = human.default_controls(1)
    bad[0, 3] = np.nan
    with pytest.raises(RigInputError, match="NaN"):
        human.evaluate(bad)


def test_misspelt_used_pattern_is_named():
    with pytest.raises(ValueError, match=r"hand_ikk"):
        build_rigify_human(used=["hand_ikk.[LR].t[xyz]"])


def test_wolf_is_a_rigify_quadruped_with_tail_and_legs():
    with build_rigify_wolf(workers=1) as wolf:
        stats = wolf.stats
        assert stats["control_bones"] >= 250 and stats["transform_channels"] >= 2000
        assert 150 <= wolf.controls.summary()["used"] <= 220 and wolf.n_joints >= 45
        assert not dead_used_controls(wolf)
        c = wolf.controls.index
        Y = wolf.default_controls(2)
        Y[1, c("spine.003.rx")] = 0.5  # the tail's base control
        X = wolf.evaluate(Y)
        moved = np.linalg.norm(X[1] - X[0], axis=1)
        tail = [joint(wolf, name) for name in ("DEF-spine", "DEF-spine.001", "DEF-spine.002")]
        assert moved[tail].min() > 1.0 and moved[joint(wolf, "DEF-front_foot.L")] < 1e-4
