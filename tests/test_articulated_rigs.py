"""The built-in articulated rigs: counts (Table 3), rest pose, protocol, Jacobians."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rig_poses import random_used_controls
from rigmap.refine import jacobian
from rigmap.rigs import RigInputError, UnknownRigError, available, load

# (min joints, min controls, min used) from the issue; the paper: 78/642/218 and 48/697-804/204
COUNTS = {"quadruped": (70, 600, 200), "biped": (45, 650, 190)}


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_counts_match_the_papers_characters(name):
    rig = load(name)
    min_joints, min_controls, min_used = COUNTS[name]
    assert rig.n_joints >= min_joints
    assert rig.n_controls >= min_controls
    assert len(rig.used_controls) >= min_used
    # unused channels are real: scales, spare attributes, FK while IK is on
    summary = rig.controls.summary()
    assert summary["by_kind"]["scale"]["total"] > 0
    assert summary["by_kind"]["scale"]["used"] == 0


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_default_controls_give_the_rest_pose(name):
    rig = load(name)
    pose = rig.pose(rig.default_controls(2))
    world = pose.positions + pose.cog[:, None, :]
    np.testing.assert_allclose(world[0], rig.rest_positions, atol=1e-9)
    # positions are relative to the centre of gravity
    np.testing.assert_allclose(pose.positions[0] + pose.cog[0], world[0])


def test_unused_scale_channel_is_a_real_channel(quadruped):
    Y = quadruped.default_controls(1)
    Y[0, quadruped.controls.index("tail_1_fk.sz")] = 1.5  # the tail points along -z
    moved = np.abs(quadruped.evaluate(Y) - quadruped.evaluate(quadruped.default_controls(1)))
    tail = [i for i, n in enumerate(quadruped.joint_names) if n.startswith("tail_")]
    assert moved[0, tail].max() > 1.0  # cm
    assert moved[0, [quadruped.joint_names.index("head")]].max() < 1e-9


def test_cog_translation_moves_cog_not_relative_positions(biped):
    Y = biped.default_controls(1)
    Y[0, biped.controls.index("cog.tx")] = 3.0
    Y[0, biped.controls.index("cog.ty")] = -6.0  # crouch a little: the feet stay reachable
    base, moved = biped.pose(biped.default_controls(1)), biped.pose(Y)
    np.testing.assert_allclose(moved.cog - base.cog, [[3.0, -6.0, 0]], atol=1e-9)
    # the feet are IK in root space: they stay, so COG-relative they move the other way
    foot = biped.joint_names.index("foot_l")
    np.testing.assert_allclose(
        moved.positions[0, foot] - base.positions[0, foot], [-3, 6, 0], atol=1e-9
    )


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_finite_difference_and_autodiff_jacobians_agree(name):
    rig = load(name)
    Y = random_used_controls(rig, 3, seed=7)
    # half-way between IK and FK, so both halves of every limb are live
    blends = [i for i, n in enumerate(rig.control_names) if n.endswith(".ik_fk")]
    Y[:, blends] = 0.5
    fd = jacobian(rig, Y, method="finite_difference")
    ad = jacobian(rig, Y, method="autodiff")
    assert fd.shape == (3, 3 * rig.n_joints, len(rig.used_controls))
    relative = np.linalg.norm(fd - ad) / np.linalg.norm(ad)
    assert relative < 1e-4
    # every used control moves some COG-relative joint, except the placement's
    # translation, which moves the COG and the whole body together
    inert = {rig.used_controls[i] for i in np.flatnonzero(np.abs(ad).max(axis=(0, 1)) < 1e-9)}
    assert inert == {"root.tx", "root.tz"}


def test_numpy_and_torch_float32_float64_agree(biped):
    Y = random_used_controls(biped, 5, seed=3)
    x64 = biped.evaluate(Y)
    x32 = biped.evaluate(Y.astype(np.float32))
    assert x64.dtype == np.float64 and x32.dtype == np.float32
    np.testing.assert_allclose(x32, x64, atol=1e-2)
    Yt = torch.tensor(Y, requires_grad=True)
    xt = biped.evaluate(Yt)
    assert isinstance(xt, torch.Tensor)
    np.testing.assert_allclose(xt.detach().numpy(), x64, atol=1e-10)
    xt.sum().backward()
    assert Yt.grad is not None and torch.isfinite(Yt.grad).all()
    single = biped.evaluate(Y[0])
    assert single.shape == (biped.n_joints, 3)


def test_large_batches_are_chunked_consistently(quadruped):
    Y = random_used_controls(quadruped, 40, seed=11)
    whole = quadruped.evaluate(Y)
    quadruped_small_chunks = type(quadruped).__new__(type(quadruped))
    quadruped_small_chunks.__dict__.update(quadruped.__dict__, _chunk=7)
    np.testing.assert_allclose(quadruped_small_chunks.evaluate(Y), whole, atol=1e-12)


def test_bad_input_gets_clear_errors(quadruped):
    with pytest.raises(RigInputError, match=r"expected controls of shape \(N, 769\)"):
        quadruped.evaluate(np.zeros((2, 10)))
    Y = quadruped.default_controls(3)
    Y[1, 5] = np.nan
    with pytest.raises(RigInputError, match=r"NaN or infinity.*row 1"):
        quadruped.evaluate(Y)
    Y[1, 5] = np.inf
    with pytest.raises(RigInputError, match=quadruped.control_names[5].replace(".", r"\.")):
        quadruped.evaluate(Y)
    with pytest.raises(UnknownRigError, match=r"available rigs: .*biped.*quadruped"):
        load("dragon")
    assert {"quadruped", "biped"} <= set(available())


def test_expand_used_fills_defaults_and_checks_shape(biped):
    used = biped.controls.used_indices
    values = np.arange(len(used), dtype=float)
    one = biped.expand_used(values)
    assert one.shape == (biped.n_controls,)
    np.testing.assert_array_equal(one[used], values)
    unused = np.setdiff1d(np.arange(biped.n_controls), used)
    np.testing.assert_array_equal(one[unused], biped.controls.defaults[unused])
    assert biped.expand_used(np.stack([values, values])).shape == (2, biped.n_controls)
    with pytest.raises(RigInputError, match=r"shape \(N, 211\)"):
        biped.expand_used(np.zeros((2, 5)))
