"""Mechanics of the feature units, checked on the built-in rigs and in isolation."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from rigmap.rigs.engine.builder import EvalContext, RigBuilder
from rigmap.rigs.features.foot_roll import FootPivots, foot_roll_attributes, reverse_foot
from rigmap.rigs.features.two_bone_ik import solve_two_bone_ik


def _world(rig, settings: dict[str, float], n: int = 1):
    Y = rig.default_controls(n)
    for name, value in settings.items():
        Y[:, rig.controls.index(name)] = value
    pose = rig.pose(Y)
    return {j: pose.positions[:, i] + pose.cog for i, j in enumerate(rig.joint_names)}, Y


def _length(a, b):
    return np.linalg.norm(a - b, axis=-1)


def test_ik_foot_reaches_its_control_when_reachable(biped):
    joints, Y = _world(
        biped, {"leg_l_ik.tx": 6.0, "leg_l_ik.ty": 25.0, "leg_l_ik.tz": 15.0, "leg_l_ik.rx": -0.4}
    )
    xf = biped.world_transforms(Y)
    np.testing.assert_allclose(joints["foot_l"][0], xf["leg_l_ik"].t[0].numpy(), atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bone_lengths_are_kept_under_ik_without_stretch(biped, seed):
    rng = np.random.default_rng(seed)
    settings = {
        f"leg_l_ik.{c}": v for c, v in zip("tx ty tz".split(), rng.uniform(-40, 40, 3), strict=True)
    }
    settings |= {"arm_r_ik.tx": rng.uniform(-60, 60), "arm_r_ik.ty": rng.uniform(-60, 60)}
    joints, _ = _world(biped, settings)
    rest = dict(zip(biped.joint_names, biped.rest_positions, strict=True))
    for a, b in [
        ("thigh_l", "shin_l"),
        ("shin_l", "foot_l"),
        ("upper_arm_r", "forearm_r"),
        ("forearm_r", "hand_r"),
    ]:
        np.testing.assert_allclose(
            _length(joints[a], joints[b]), _length(rest[a], rest[b]), rtol=1e-9
        )


def test_stretch_lets_an_unreachable_foot_reach(biped):
    far = {"leg_l_ik.ty": -40.0, "leg_l_ik.tz": 30.0}  # below the floor and forward
    stiff, Y = _world(biped, far)
    stretchy, _ = _world(biped, far | {"leg_l.stretch": 1.0})
    target = biped.world_transforms(Y)["leg_l_ik"].t[0].numpy()
    assert _length(stiff["foot_l"][0], target) > 10.0  # cm short of the control
    np.testing.assert_allclose(stretchy["foot_l"][0], target, atol=1e-6)


def test_two_bone_ik_keeps_the_knee_in_the_pole_plane():
    root = torch.zeros(4, 3, dtype=torch.float64)
    target = torch.tensor(
        [[0, -50, 10], [5, -70, 0], [0, -30, 30], [10, -60, 5]], dtype=torch.float64
    )
    pole = torch.tensor([[0, -40, 50]] * 4, dtype=torch.float64)
    sol = solve_two_bone_ik(root, target, pole, 40.0, 40.0)
    np.testing.assert_allclose(torch.linalg.norm(sol.mid - root, dim=-1), 40.0, rtol=1e-9)
    np.testing.assert_allclose(torch.linalg.norm(sol.end - sol.mid, dim=-1), 40.0, rtol=1e-9)
    # the knee lies in the plane through root, target and pole, on the pole's side
    normal = torch.linalg.cross(target - root, pole - root, dim=-1)
    assert torch.abs((normal * (sol.mid - root)).sum(-1)).max() < 1e-9
    assert ((sol.mid - root) * (pole - root)).sum(-1).min() > 0


def test_foot_roll_pivots_about_heel_then_ball_then_toe():
    b = RigBuilder("foot")
    attrs = foot_roll_attributes(b, "foot", group="leg", used=("roll",))
    pivots = FootPivots(
        ankle=(0, 0, 0),
        heel=(0, -9, -4),
        ball=(0, -7.5, 13),
        toe=(0, -7.5, 20),
        inner=(-4, -7.5, 13),
        outer=(4, -7.5, 13),
    )
    rolls = np.linspace(-0.7, 1.5, 45)
    Y = np.tile([c.default for c in b.controls], (len(rolls), 1))
    Y[:, attrs.roll.column] = rolls
    out = reverse_foot(EvalContext(torch.tensor(Y)), pivots, attrs)
    heel, ball, toe, ankle = (
        out.heel.t.numpy(),
        out.ball.t.numpy(),
        out.toe.t.numpy(),
        out.ankle.t.numpy(),
    )
    back, peel, tip = rolls < 0, (rolls > 0) & (rolls < 0.6), rolls > 0.6
    np.testing.assert_allclose(heel[back], np.tile(pivots.heel, (back.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(ball[peel], np.tile(pivots.ball, (peel.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(toe[tip], np.tile(pivots.toe, (tip.sum(), 1)), atol=1e-12)
    # and in each phase the ankle really moves: the roll does something
    for phase in (back, peel, tip):
        assert np.ptp(ankle[phase], axis=0).max() > 1.0
    # the toes stay planted while the heel peels off the ball
    np.testing.assert_allclose(toe[peel], np.tile(pivots.toe, (peel.sum(), 1)), atol=1e-12)


def test_foot_roll_on_the_rig_plants_ball_then_toe(biped):
    rest = dict(zip(biped.joint_names, biped.rest_positions, strict=True))
    for roll, planted in [(0.3, "ball_l"), (0.55, "ball_l"), (0.9, "toe_l"), (1.3, "toe_l")]:
        joints, _ = _world(biped, {"leg_l.roll": roll})
        np.testing.assert_allclose(joints[planted][0], rest[planted], atol=1e-6)
        assert _length(joints["foot_l"][0], rest["foot_l"]) > 1.0


def test_eyes_aim_at_their_target(quadruped):
    joints, Y = _world(quadruped, {"eye_aim.tx": 40.0, "eye_aim.ty": -20.0, "head.ry": 0.3})
    target = quadruped.world_transforms(Y)["eye_l_aim"].t[0].numpy()
    look = joints["eye_end_l"][0] - joints["eye_l"][0]
    want = target - joints["eye_l"][0]
    cosine = look @ want / np.linalg.norm(look) / np.linalg.norm(want)
    assert cosine == pytest.approx(1.0, abs=1e-12)


def test_head_follow_blends_between_neck_and_world_space(quadruped):
    def head_direction(follow):
        joints, _ = _world(quadruped, {"neck_1_fk.rx": 0.5, "head.follow": follow})
        d = joints["head_end"][0] - joints["head"][0]
        return d / np.linalg.norm(d)

    rest = quadruped.rest_positions
    names = quadruped.joint_names
    rest_dir = rest[names.index("head_end")] - rest[names.index("head")]
    rest_dir /= np.linalg.norm(rest_dir)
    np.testing.assert_allclose(head_direction(0.0), rest_dir, atol=1e-12)  # world space
    assert np.arccos(np.clip(head_direction(1.0) @ rest_dir, -1, 1)) == pytest.approx(0.5)
    half = np.arccos(np.clip(head_direction(0.5) @ rest_dir, -1, 1))
    assert 0.1 < half < 0.4


def test_tail_curl_spreads_the_bend_along_the_chain(quadruped):
    curl = 1.2
    joints, _ = _world(quadruped, {"tail.curl": curl})
    rest = dict(zip(quadruped.joint_names, quadruped.rest_positions, strict=True))

    def angle(a, b):
        u, v = joints[b][0] - joints[a][0], rest[b] - rest[a]
        return np.arccos(u @ v / np.linalg.norm(u) / np.linalg.norm(v))

    assert angle("tail_12", "tail_tip") == pytest.approx(curl, abs=1e-9)
    assert angle("tail_1", "tail_2") == pytest.approx(curl / 12, abs=1e-9)


def test_spline_spine_bends_smoothly_and_can_preserve_length(biped):
    joints, _ = _world(biped, {"chest.tz": 8.0})
    spine = ["pelvis", "spine_1", "spine_2", "spine_3", "spine_chest"]
    rest = dict(zip(biped.joint_names, biped.rest_positions, strict=True))
    moved = [_length(joints[j][0], rest[j]) for j in spine]
    assert moved[0] < 1e-9 and all(np.diff(moved) > 0)  # monotone from hips to chest
    assert moved[-1] == pytest.approx(8.0)
    # tilting the chest in place turns the top of the curve with it, smoothly
    tilted, _ = _world(biped, {"chest.rx": 0.6})
    leans = [
        np.arctan2(*(tilted[b][0] - tilted[a][0])[[2, 1]]) for a, b in itertools.pairwise(spine)
    ]
    assert 0.2 < leans[-1] < 0.6
    assert np.abs(np.diff(leans)).max() < 0.4  # no kinks between vertebrae
    free, _ = _world(biped, {"chest.ty": 10.0})
    kept, _ = _world(biped, {"chest.ty": 10.0, "pelvis_spine.stretch": 0.0})

    def total(js):
        return sum(_length(js[a][0], js[b][0]) for a, b in itertools.pairwise(spine))

    assert total(free) == pytest.approx(50.0, abs=1e-6)  # stretched by the 10 cm
    assert total(kept) == pytest.approx(40.0, abs=1e-6)


def test_ik_fk_blend_switches_between_the_two_chains(biped):
    fk_bent = {"upper_arm_l_fk.rz": -1.0, "arm_l.ik_fk": 0.0}
    joints_fk, _ = _world(biped, fk_bent)
    joints_ik, _ = _world(biped, fk_bent | {"arm_l.ik_fk": 1.0})
    rest = dict(zip(biped.joint_names, biped.rest_positions, strict=True))
    assert _length(joints_fk["hand_l"][0], rest["hand_l"]) > 20.0  # FK arm swung down
    np.testing.assert_allclose(joints_ik["hand_l"][0], rest["hand_l"], atol=1e-9)  # IK holds
    half, _ = _world(biped, fk_bent | {"arm_l.ik_fk": 0.5})
    np.testing.assert_allclose(
        half["hand_l"][0], 0.5 * (joints_fk["hand_l"][0] + joints_ik["hand_l"][0]), atol=1e-9
    )


def test_torso_and_head_units_build_a_rig_on_their_own():
    from rigmap.rigs.engine.torch_rig import TorchRig
    from rigmap.rigs.features.head import HeadSpec, head
    from rigmap.rigs.features.torso import TorsoSpec, torso

    b = RigBuilder("bust")
    torso(b, TorsoSpec(cog=(0, 100, 0), hips=(0, 0, 0), chest=(0, 40, 0), spine_mid=(0, 20, 0),
                       spine=("pelvis", "spine_1", "spine_chest")))  # fmt: skip
    ears = []
    spec = HeadSpec(neck=((0, 148, 0), (0, 155, 1)), head=(0, 162, 2), head_end=(0, 180, 2),
                    jaw=(0, 163, 5), jaw_end=(0, 156, 11), jaw_open=0.5, eye_aim=(0, 168, 70),
                    eye=(3.0, 168, 8), pupil=1.0)  # fmt: skip
    head(b, spec, parent="spine_chest", per_side=lambda side, sign: ears.append((side, sign)))
    rig = TorchRig(b)
    assert ears == [("l", 1.0), ("r", -1.0)]  # one call after each eye
    assert rig.joint_names[-4:] == ["eye_l", "eye_end_l", "eye_r", "eye_end_r"]
    assert rig.controls["jaw_ctrl.rx"].upper == 0.5
    assert {"root.tx", "cog.ty", "chest.rz", "spine_mid.tz", "neck_2_fk.rx", "head.follow"} <= set(
        rig.used_controls
    )
    # the rest pose puts the joints where the specs say; the eyes look along +Z at rest
    world = dict(zip(rig.joint_names, rig.rest_positions, strict=True))
    np.testing.assert_allclose(world["head"], [0, 162, 2])
    np.testing.assert_allclose(world["eye_end_r"] - world["eye_r"], [0, 0, 1.0], atol=1e-12)
    joints, _ = _world(rig, {"eye_aim.tx": 60.0})  # look 60 cm to the character's left
    gaze = joints["eye_end_l"][0] - joints["eye_l"][0]
    assert gaze[0] > 0.5 and abs(np.linalg.norm(gaze) - 1.0) < 1e-9


@pytest.mark.parametrize("name", ["biped", "quadruped"])
def test_traced_pose_equals_the_eager_rig(name):
    """The TorchScript trace of a rig gives the eager evaluation's numbers on random controls
    across the soft ranges, IK/FK switches and stretch included (no step branches on values)."""
    from rigmap.rigs import load

    rig = load(name)
    rng = np.random.default_rng(5)
    used = rig.controls.used_indices
    Y = np.repeat(rig.controls.defaults[None], 6, axis=0)
    Y[:, used] = rng.uniform(rig.controls.lower[used], rig.controls.upper[used], (6, len(used)))
    eager = rig.pose(Y)
    with torch.no_grad():
        traced = rig.traced_pose(6)(torch.from_numpy(Y))
    for got, want in zip(traced, eager, strict=True):
        np.testing.assert_allclose(got.numpy(), want, rtol=0, atol=1e-9)
    assert rig.traced_pose(6) is rig.traced_pose(6)  # cached per batch size


@pytest.mark.parametrize("name", ["biped", "quadruped"])
def test_one_trace_replays_batches_of_every_size(name):
    """The generic trace (recorded on 16 poses) gives the eager numbers at other batch sizes,
    one pose and a batch split at the call size included."""
    from rigmap.rigs import load
    from rigmap.rigs.engine.torch_rig import TRACED_POSES_PER_CALL

    rig = load(name)
    assert rig.generic_trace() is not None
    rng = np.random.default_rng(8)
    used = rig.controls.used_indices
    for n in (1, 23, TRACED_POSES_PER_CALL + 5):
        Y = np.repeat(rig.controls.defaults[None], n, axis=0)
        Y[:, used] = rng.uniform(rig.controls.lower[used], rig.controls.upper[used], (n, len(used)))
        eager = rig.pose(Y)
        with rig.replaying_traces():
            replayed = rig.pose(Y)
        for got, want in zip(replayed, eager, strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)


def _matmul_product(rotations):
    """The axis rotations' product by batched matmuls (``R_k @ … @ R_1``)."""
    from rigmap.rigs.engine.transforms import axis_rotation

    R = axis_rotation(*rotations[0])
    for angle, axis in rotations[1:]:
        R = axis_rotation(angle, axis) @ R
    return R


def test_rotation_product_equals_the_matmul_product_to_the_last_bit():
    """Euler matrices and two-axis rotations written out entry by entry are the batched
    matmuls of the axis matrices exactly (every order; angles across several turns), and
    their gradients agree."""
    from rigmap.rigs.engine.transforms import ROTATION_ORDERS, euler_matrix, rotation_product

    rng = np.random.default_rng(3)
    angles = torch.from_numpy(rng.uniform(-7.0, 7.0, (257, 4, 3)))
    for order in ROTATION_ORDERS:
        want = _matmul_product([(angles[..., "xyz".index(a)], a) for a in order])
        assert torch.equal(euler_matrix(angles, order), want), order
    for first, second in itertools.permutations("xyz", 2):
        pair = [(angles[..., 0], first), (angles[..., 1], second)]
        assert torch.equal(rotation_product(pair), _matmul_product(pair)), (first, second)
    x = angles[:5, 0].clone().requires_grad_(True)
    (rotation_product([(x[:, 0], "z"), (x[:, 2], "x")]) ** 2).sum().backward()
    y = angles[:5, 0].clone().requires_grad_(True)
    (_matmul_product([(y[:, 0], "z"), (y[:, 2], "x")]) ** 2).sum().backward()
    torch.testing.assert_close(x.grad, y.grad, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="rotation order"):
        euler_matrix(angles, "xxy")


@pytest.mark.parametrize("name", ["biped", "quadruped"])
def test_rigs_pose_as_with_session_28s_code(name, monkeypatch):
    """The built-in rigs give the positions of session 28's code (matmul-product rotations,
    layered chains joint by joint, pose-major local transforms) to the last bit, eager and
    traced, and one trace still replays every batch size."""
    from rigmap.rigs import load
    from rigmap.rigs.engine import builder
    from rigmap.rigs.features import chain_attributes, fk_chain, foot_roll

    rng = np.random.default_rng(11)
    rig = load(name)
    used = rig.controls.used_indices
    Y = np.repeat(rig.controls.defaults[None], 40, axis=0)
    Y[:, used] = rng.uniform(rig.controls.lower[used], rig.controls.upper[used], (40, len(used)))
    new = rig.pose(Y)
    assert rig.generic_trace() is not None
    with rig.replaying_traces():
        new_traced = rig.pose(Y)
    monkeypatch.setattr(
        builder,
        "euler_matrix",
        lambda angles, order="xyz": _matmul_product(
            [(angles[..., "xyz".index(a)], a) for a in order]
        ),
    )
    monkeypatch.setattr(chain_attributes, "rotation_product", _matmul_product)
    monkeypatch.setattr(foot_roll, "rotation_product", _matmul_product)
    monkeypatch.setattr(fk_chain, "BATCHED_LAYERS", False)
    monkeypatch.setattr(builder, "CONTROL_MAJOR_LOCALS", False)
    old = load(name).pose(Y)
    for got, traced, want in zip(new, new_traced, old, strict=True):
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(traced, want)


@pytest.mark.parametrize("side", [False, True])
@pytest.mark.parametrize("wave", [False, True])
def test_chain_layer_rotations_at_once_equal_the_joint_by_joint_ones(side, wave):
    """``ChainAttributes.rotations`` (every joint of a chain in one batch) gives each joint's
    ``rotation`` to the last bit, with and without side curl and wave."""
    from rigmap.rigs.engine.builder import Attribute
    from rigmap.rigs.features.chain_attributes import ChainAttributes

    rng = np.random.default_rng(4)
    layer = ChainAttributes(
        curl=Attribute("curl", 0),
        side_curl=Attribute("side", 1) if side else None,
        wave_amplitude=Attribute("amplitude", 2) if wave else None,
        wave_phase=Attribute("phase", 3) if wave else None,
        bend_axis="z",
        side_axis="y",
        wavelength=1.3,
        bend_sign=-1.0,
    )
    ctx = EvalContext(torch.from_numpy(rng.uniform(-4.0, 4.0, (33, 4))))
    count = 7
    together = layer.rotations(ctx, count)
    assert together.shape == (33, count, 3, 3)
    for index in range(count):
        assert torch.equal(together[:, index], layer.rotation(ctx, index, count)), index
