"""Table 1's Script row on a Blender rig: the evaluation runs the wolf's constraint retarget.

Needs the Blender worker environment; a few frames of one test clip, about a second.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.animation.library import build_clips, build_corpus
from rigmap.evaluation import run_method
from rigmap.evaluation.methods import TestClip, TestSet
from rigmap.evaluation.metrics import control_std, joint_error
from rigmap.retarget import NoRetargetScriptError, script_retarget
from rigmap.rigs import load

pytestmark = [
    pytest.mark.blender,
]
WOLF = "rigify_wolf"


@pytest.fixture(scope="module")
def wolf():
    return load(WOLF)


@pytest.fixture(scope="module")
def gallop(wolf):
    """Every 6th frame of the held-out gallop, posed by the wolf: the targets and the truth."""
    clip = next(c for c in build_clips(WOLF, "test", seed=0) if c.name == "Turning & Galloping")
    rows = np.arange(0, clip.n_frames, 6)
    Y = clip.evaluate(wolf.control_names, wolf.controls.defaults)[rows]
    pose = wolf.pose(Y)
    used = wolf.controls.used_indices
    return TestSet(
        WOLF,
        [TestClip(clip.name, clip.frames[rows], *pose, Y[:, used])],
        list(wolf.used_controls),
        [wolf.controls.kinds[i] for i in used],
        control_std(build_corpus(wolf, "train", seed=0).values()),
    )


def test_script_method_retargets_the_wolf_and_counts_one_solve_per_frame(wolf, gallop):
    target = gallop.clips[0]
    evaluation = run_method(wolf, "script", gallop, warmup_frames=1)
    result = evaluation.result.clips[0]
    rest = joint_error(wolf.evaluate(wolf.default_controls(len(target))), target.positions)
    scripted = np.asarray(result.joint_error_per_frame)
    print(f"\nwolf script on {len(target)} gallop frames: joint error {scripted.mean():.3g} cm², "
          f"rest pose {rest.per_frame.mean():.4g} cm²")  # fmt: skip
    assert scripted.mean() < 0.1 * rest.per_frame.mean()
    assert (scripted < rest.per_frame).all()
    assert result.rig_evaluations == len(target)  # Blender solves the constraints once a frame
    assert result.rig_calls == 1
    direct = script_retarget(wolf, target.positions, target.cog, target.cog_rotation)
    assert direct.rig_evaluations == len(target)
    np.testing.assert_allclose(evaluation.controls[wolf.used_controls].to_numpy(), direct.Y_used)
    # the torso follows the target COG placement exactly
    got = wolf.pose(wolf.expand_used(direct.Y_used))
    np.testing.assert_allclose(got.cog, target.cog, atol=1e-2)  # cm


def test_a_blender_rig_without_a_retarget_mapping_has_no_script(wolf):
    class Unmapped:
        name = "blend_file:hero"
        retarget_mapping = ()
        n_joints = wolf.n_joints

        def constraint_retarget(self, *args):
            raise AssertionError("must not be called")

    pose = wolf.pose(wolf.default_controls(1))
    with pytest.raises(NoRetargetScriptError, match="'retarget' mapping"):
        script_retarget(Unmapped(), pose)
