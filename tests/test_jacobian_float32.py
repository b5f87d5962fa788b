"""Finite differences on a rig that computes in float32 (as Blender's armatures do).

Blender keeps control values and bone matrices in float32 whatever dtype rigmap sends, so
the float64 default step (1e-6) drowns in rounding; a rig that says so
(``computes_in_float32``) gets the float32 step, through the map's wrappers too.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.map.prior_refinement import PriorRig
from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.refine import jacobian
from rigmap.rigs.base import Pose, Rig


class Float32Rig(Rig):
    """The biped with its controls and joint positions rounded to float32."""

    def __init__(self, inner: Rig, *, flagged: bool):
        self.inner = inner
        self.name = inner.name
        self.controls = inner.controls
        self.joint_names = list(inner.joint_names)
        self.parents = inner.parents
        self.computes_in_float32 = flagged

    def _pose(self, Y) -> Pose:
        Y32 = np.asarray(Y, dtype=np.float32).astype(np.float64)
        pose = self.inner.pose(Y32)
        return Pose(*(np.asarray(p, dtype=np.float32).astype(np.float64) for p in pose))


@pytest.fixture(scope="module")
def frames(biped):
    rng = np.random.default_rng(3)
    Y = biped.default_controls(2)
    used = biped.controls.used_indices
    span = biped.controls.upper[used] - biped.controls.lower[used]
    Y[:, used] += 0.05 * span * rng.standard_normal((2, len(used)))
    return np.clip(Y, biped.controls.lower, biped.controls.upper)


def relative_error(J, exact) -> float:
    return float(np.linalg.norm(J - exact) / np.linalg.norm(exact))


def test_a_float32_rig_gets_a_step_its_rounding_does_not_drown(biped, frames):
    joints = ["hand_l", "foot_r", "head", "pelvis"]
    exact = jacobian(WorldSubsetRig(biped, joints), frames, differences="central")
    errors = {}
    for flagged in (True, False):
        view = WorldSubsetRig(Float32Rig(biped, flagged=flagged), joints)
        assert view.computes_in_float32 is flagged
        errors[flagged] = relative_error(jacobian(view, frames, differences="forward"), exact)
    assert errors[True] < 0.01
    # the float64 step on the same float32 numbers is many times further off
    assert errors[False] > 10 * errors[True]


def test_the_prior_rig_passes_the_flag_on(biped, frames):
    view = WorldSubsetRig(Float32Rig(biped, flagged=True), ["hand_l", "head"])
    prior = PriorRig(view, np.ones(len(biped.controls.used_indices)))
    assert prior.computes_in_float32
    exact = jacobian(PriorRig(WorldSubsetRig(biped, ["hand_l", "head"]),
                              np.ones(len(biped.controls.used_indices))), frames)  # fmt: skip
    assert relative_error(jacobian(prior, frames, differences="forward"), exact) < 0.01
