"""WorldSubsetRig: refinement on world targets of a few joints, root channels included."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.refine import ComputedJacobian, damped_least_squares
from rigmap.refine.jacobian import jacobian
from rigmap.rigs import RigInputError

EFFECTORS = ["pelvis", "head", "hand_l", "hand_r", "foot_l", "foot_r", "spine_chest"]


def test_positions_are_world_positions_of_the_subset(biped):
    rng = np.random.default_rng(0)
    Y = biped.default_controls(3)
    Y[:, biped.controls.used_indices] += rng.normal(0, 0.05, (3, len(biped.used_controls)))
    view = WorldSubsetRig(biped, EFFECTORS)
    pose = biped.pose(Y)
    columns = [biped.joint_names.index(j) for j in EFFECTORS]
    want = pose.positions[:, columns] + pose.cog[:, None]
    np.testing.assert_allclose(view.evaluate(Y), want, atol=1e-12)
    torch_out = view.evaluate(torch.as_tensor(Y))
    np.testing.assert_allclose(torch_out.numpy(), want, atol=1e-9)
    J_view = jacobian(view, Y)
    assert J_view.shape == (3, 3 * len(EFFECTORS), len(biped.used_controls))
    assert np.abs(J_view).max() > 0.5  # the root channels move the world positions
    with pytest.raises(RigInputError, match=r"has no joints \['wing'\]"):
        WorldSubsetRig(biped, ["pelvis", "wing"])


def test_refinement_recovers_a_moved_character_from_seven_effectors(biped):
    rng = np.random.default_rng(4)
    used = biped.controls.used_indices
    truth = biped.controls.defaults[used] + rng.normal(0, 0.03, (2, len(used)))
    names = biped.used_controls
    for channel, offset in (("root.tx", 80.0), ("root.tz", -45.0)):
        truth[:, names.index(channel)] += offset
    view = WorldSubsetRig(biped, EFFECTORS)
    target = view.evaluate(biped.expand_used(truth))
    start = np.tile(biped.controls.defaults[used], (2, 1))
    before = ((view.evaluate(biped.expand_used(start)) - target) ** 2).mean()
    result = damped_least_squares(view, start, target, ComputedJacobian(view), damping=0.1,
                                  max_iterations=6, tolerance=1e-8)  # fmt: skip
    after = ((view.evaluate(biped.expand_used(result.Y_used)) - target) ** 2).mean()
    assert before > 500.0  # metres away at the start
    assert after < 1e-3 * before  # the root channels moved it there: COG-relative could not
