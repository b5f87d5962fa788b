"""Left/right mirroring of edit training data (002 §7.1) on real rig evaluations."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import rigmap.rigs
from rigmap.edits.mirror import (
    ChannelMirror,
    Mirror,
    subject_mirror,
    swap_bvh_side,
    symmetric_skeleton,
)
from rigmap.edits.representation import TargetError
from rigmap.edits.rig_mode import full_controls, rig_controls
from rigmap.edits.skeleton_mode import skeleton_positions
from rigmap.edits.subjects import rig_clip, rig_subject, skeleton_clip, skeleton_subject

WALK = Path(__file__).resolve().parents[2] / "shared/mocap/cmu_131_01_walk.bvh"


@pytest.fixture(scope="module")
def biped():
    rig = rigmap.rigs.load("biped")
    return rig, rig_subject(rig)


def world_positions(rig, used_values):
    controls = full_controls(used_values, rig.controls.used_indices, rig.controls.defaults)
    with threadpool_limits(limits=1):
        pose = rig.pose(controls)
    return np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]


def random_poses(rig, frames, seed):
    """Used controls drawn across their limits (a quarter of each range around the default,
    the IK/FK blends anywhere in [0, 1]): poses far from the symmetric rest pose."""
    rng = np.random.default_rng(seed)
    used = rig.controls.used_indices
    lower = np.asarray(rig.controls.lower, dtype=float)[used]
    upper = np.asarray(rig.controls.upper, dtype=float)[used]
    default = np.asarray(rig.controls.defaults, dtype=float)[used]
    span = np.where(np.isfinite(upper - lower), upper - lower, 2.0)
    values = default + 0.25 * span * rng.uniform(-1, 1, (frames, len(used)))
    values = np.clip(values, lower, upper)
    for k, name in enumerate(rig.used_controls):
        if name.endswith("ik_fk"):
            values[:, k] = rng.uniform(0, 1, frames)
    return values


def test_rig_of_mirrored_controls_is_the_reflected_rig(biped):
    rig, subject = biped
    mirror = ChannelMirror.by_names(rig.used_controls)
    joints = Mirror.for_rig(subject.channels.channels(), rig.joint_names)
    poses = random_poses(rig, 12, seed=0)
    reflected = joints.positions(world_positions(rig, poses))
    mirrored = world_positions(rig, mirror(poses))
    extent = np.abs(reflected).max()
    assert extent > 100  # cm: the whole character, not a degenerate pose
    np.testing.assert_allclose(mirrored, reflected, atol=1e-3)  # cm
    # and the mirror is not the identity: the poses are asymmetric
    assert np.abs(world_positions(rig, poses) - reflected).max() > 5.0
    # a wrong sign is caught: flipping rx instead of ry breaks the identity
    wrong = ChannelMirror.by_names(rig.used_controls, flipped=frozenset({"tx", "rx", "rz"}))
    assert np.abs(world_positions(rig, wrong(poses)) - reflected).max() > 1.0


def test_mirrored_track_integrates_to_the_mirrored_controls_and_positions(biped):
    rig, subject = biped
    mirror = subject_mirror(subject)
    track = rig_clip(rig, subject.channels, "Walk", 0)
    mirrored = mirror.track(track)
    controls = ChannelMirror.by_names(rig.used_controls)
    np.testing.assert_allclose(
        rig_controls(mirrored, subject.channels),
        controls(rig_controls(track, subject.channels)),
        atol=1e-9,
    )
    np.testing.assert_allclose(mirror.track(mirrored).values, track.values, atol=1e-12)
    source = subject.source(track)
    np.testing.assert_allclose(
        subject.source(mirrored).positions, mirror.positions(source.positions), atol=1e-3
    )
    pairs = mirror.pairs([(source, track)])
    assert len(pairs) == 2 and pairs[1][1].source.endswith("(mirrored)")


def test_mirror_names_and_bad_channels():
    assert swap_bvh_side("LeftUpLeg") == "RightUpLeg"
    assert swap_bvh_side("RHipJoint") == "LHipJoint"
    assert swap_bvh_side("Hips") == "Hips"
    with pytest.raises(TargetError, match=r"no other-side twin 'hand_r\.rx'"):
        ChannelMirror.by_names(["hand_l.rx", "hips.rx"])
    with pytest.raises(TargetError, match="columns"):
        ChannelMirror.by_names(["hips.rx"])(np.zeros((2, 3)))


def test_skeleton_mirror_is_exact_on_the_symmetrised_cmu_skeleton():
    subject = skeleton_subject(WALK, 1.0, "cmu_131")
    track = skeleton_clip(subject, WALK).frames(300, 420)
    mirror = subject_mirror(subject)
    symmetric = symmetric_skeleton(subject.skeleton)
    reflected = mirror.positions(skeleton_positions(track, symmetric))
    mirrored = skeleton_positions(mirror.track(track), symmetric)
    np.testing.assert_allclose(mirrored, reflected, atol=1e-9)
    assert np.abs(reflected - skeleton_positions(track, symmetric)).max() > 1.0  # units
    # the captured skeleton itself is nearly symmetric: within a few units, hands included
    captured = skeleton_positions(mirror.track(track), subject.skeleton)
    error = np.abs(captured - mirror.positions(skeleton_positions(track, subject.skeleton)))
    assert error.max() < 2.0  # BVH units (≈ 5 cm)
