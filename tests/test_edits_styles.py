"""The style edits of 002 §7.2 (Hsu et al.'s swaying, crouching and jogging walks) as
procedural edits, on real clips: the biped's Walk and the CMU walk 131_02."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import rigmap.rigs
from rigmap.animation import read_bvh
from rigmap.edits.authoring import bone_length_ik
from rigmap.edits.procedural import Edit, EditConfigError, crouch_legs, gait_phase
from rigmap.edits.representation import TargetTrack
from rigmap.edits.skeleton_mode import Skeleton, skeleton_positions, skeleton_targets
from rigmap.edits.subjects import rig_clip, rig_subject

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared/mocap/cmu_131_02_walk.bvh"
EDITS = ROOT / "conf/edit"
CM = 6.0  # cm per CMU unit for these tests (the stages measure it from the biped's leg)


def config(name: str) -> dict:
    return yaml.safe_load((EDITS / f"{name}.yaml").read_text())


def edit(name: str, mode: str, amount: float | None = None) -> Edit:
    """The conf/edit edit, or with every operation's amount replaced by ``amount``."""
    data = config(name)
    if amount is not None:
        for op in data["operations"][mode]:
            op["amount"] = amount
    return Edit.from_config(name, data, mode)


@pytest.fixture(scope="module")
def biped():
    rig = rigmap.rigs.load("biped")
    subject = rig_subject(rig)
    walk = rig_clip(rig, subject.channels, "Walk", 0)
    idle = rig_clip(rig, subject.channels, "Idle", 0)
    return rig, subject, walk, idle


@pytest.fixture(scope="module")
def cmu():
    motion = read_bvh(WALK)
    return Skeleton.of(motion), skeleton_targets(motion)


def lengths(positions, parents):
    return np.stack(
        [
            np.linalg.norm(positions[:, j] - positions[:, p], axis=1)
            for j, p in enumerate(parents)
            if p >= 0
        ],
        axis=1,
    )


def test_crouch_lowers_the_pelvis_with_feet_planted_and_bones_kept_on_the_biped(biped):
    rig, subject, walk, _ = biped
    names = list(rig.joint_names)
    before = subject.positions(walk)
    after = subject.positions(edit("crouch", "rig").apply(walk))
    pelvis = names.index("pelvis")
    np.testing.assert_allclose(before[:, pelvis, 1] - after[:, pelvis, 1], 12.0, atol=1e-6)
    for foot in ("foot_l", "foot_r", "toe_l", "toe_r"):
        np.testing.assert_allclose(
            after[:, names.index(foot)], before[:, names.index(foot)], atol=1e-6
        )
    for a, b in (
        ("thigh_l", "shin_l"),
        ("shin_l", "foot_l"),
        ("thigh_r", "shin_r"),
        ("shin_r", "foot_r"),
    ):
        i, j = names.index(a), names.index(b)
        np.testing.assert_allclose(
            np.linalg.norm(after[:, i] - after[:, j], axis=1),
            np.linalg.norm(before[:, i] - before[:, j], axis=1),
            atol=1e-6,
        )
    assert np.array_equal(edit("crouch", "rig", amount=0.0).apply(walk).values, walk.values)


def test_crouch_of_the_cmu_walk_lowers_the_hips_with_ankles_pinned_and_hinge_knees(cmu):
    skeleton, track = cmu
    names = list(skeleton.joint_names)
    crouched = edit("crouch", "skeleton").apply(track, CM, skeleton)
    before = skeleton_positions(track, skeleton)
    after = skeleton_positions(crouched, skeleton)
    drop = 12.0 / CM
    np.testing.assert_allclose(before[:, 0, 1] - after[:, 0, 1], drop, atol=1e-9)
    legs = [names.index(n) for n in ("LeftAnkle", "RightAnkle", "LeftToe", "RightToe")]
    np.testing.assert_allclose(after[:, legs], before[:, legs], atol=1e-6)  # feet planted
    np.testing.assert_allclose(
        lengths(after, skeleton.parents), lengths(before, skeleton.parents), atol=1e-6
    )
    knee = names.index("LeftKnee")
    assert np.mean(after[:, knee, 1] < before[:, knee, 1] - 0.2 * drop) > 0.99  # knees bend
    # the knee is on the circle the bone-length IK allows with the hip lowered and the ankle
    # pinned, near the IK's point (which is nearest the old knee; ours keeps the leg's twist)
    hip, ankle = names.index("LeftHip"), names.index("LeftAnkle")
    gaps = []
    for frame in range(0, track.n_frames, 50):
        chain = before[frame, [hip, knee, ankle]].copy()
        goal = chain - [[0.0, drop, 0.0], [0.0, drop, 0.0], [0.0, 0.0, 0.0]]
        solved, _ = bone_length_ik(chain, np.array([-1, 0, 1]), goal, {0: goal[0], 2: chain[2]})
        np.testing.assert_allclose(after[frame, hip], solved[0], atol=1e-9)
        gaps.append(np.linalg.norm(after[frame, knee] - solved[1]) * CM)
    assert np.median(gaps) < 1.0  # cm (the IK flips its bend plane where the leg is straight)
    # the knees bend about their hinge axis: the CMU knee's third channel stays at its noise
    column = track.column("LeftKnee.z")
    assert np.abs(crouched.values[:, column] - track.values[:, column]).max() < 1e-5
    # and smoothly: no channel's edit jumps between frames (120 fps)
    assert np.abs(np.diff(crouched.values - track.values, axis=0)).max() < 0.05
    none = edit("crouch", "skeleton", amount=0.0).apply(track, CM, skeleton)
    np.testing.assert_allclose(none.values, track.values, atol=1e-9)


def test_crouch_names_what_it_cannot_do(cmu, biped):
    skeleton, track = cmu
    with pytest.raises(EditConfigError, match="needs the track's skeleton"):
        edit("crouch", "skeleton").apply(track, CM)
    with pytest.raises(EditConfigError, match="cannot reach its ankle at frame 0"):
        crouch_legs(track, skeleton, ["LeftAnkle"], np.full(track.n_frames, -10.0))
    with pytest.raises(EditConfigError, match="'Hips' is not an ankle"):
        crouch_legs(track, skeleton, ["Hips"], 1.0)
    with pytest.raises(EditConfigError, match="crouch is a skeleton-mode operation"):
        Edit.from_config(
            "c",
            {"operations": {"rig": [{"kind": "crouch", "targets": ["foot_l"], "amount": 5.0}]}},
            "rig",
        )
    with pytest.raises(EditConfigError, match="needs a phase channel"):
        Edit.from_config(
            "s",
            {
                "operations": {
                    "rig": [{"kind": "oscillate", "targets": ["chest.rz"], "amount": 0.1}]
                }
            },
            "rig",
        )
    bad_phase = {
        "operations": {
            "rig": [
                {"kind": "oscillate", "targets": ["chest.rz"], "amount": 0.1, "phase": "leg_l.tz"}
            ]
        }
    }
    with pytest.raises(EditConfigError, match=r"channel 'leg_l\.tz'.*did you mean"):
        Edit.from_config("s", bad_phase, "rig").apply(biped[2])


def test_gait_phase_of_a_sinusoid_and_sway_follows_it():
    fps, frames = 30.0, 300
    t = np.arange(frames) / fps
    omega = 2.0 * np.pi * 1.0  # one stride a second
    phase = gait_phase(3.0 + 2.0 * np.cos(omega * t), fps, 1.0)
    inner = slice(45, -45)  # away from the ends, where the moving average and Hilbert bend
    np.testing.assert_allclose(np.sin(phase[inner]), np.sin(omega * t[inner]), atol=0.05)
    assert np.array_equal(gait_phase(np.full(frames, 2.0), fps, 1.0), np.zeros(frames))
    values = np.zeros((frames, 6))
    values[:, 0] = 1.0 / fps
    values[:, 4] = np.cos(omega * t)  # the phase channel
    track = TargetTrack(
        ("dt", "root.step_forward", "root.step_lateral", "root.turn", "foot.tz", "chest.rz"),
        values,
        fps,
        (0.0, 0.0, 0.0),
    )
    swayed = Edit.from_config(
        "s",
        {
            "operations": {
                "rig": [
                    {
                        "kind": "oscillate",
                        "targets": ["chest.rz"],
                        "amount": 0.1,
                        "phase": "foot.tz",
                    }
                ]
            }
        },
        "rig",
    ).apply(track)
    np.testing.assert_allclose(swayed.values[inner, 5], 0.1 * np.sin(omega * t[inner]), atol=0.005)
    np.testing.assert_array_equal(swayed.values[:, :5], values[:, :5])


def test_sway_rolls_the_upper_body_toward_the_stance_foot_while_walking(biped, cmu):
    rig, subject, walk, idle = biped
    names = list(rig.joint_names)
    head, pelvis = names.index("head"), names.index("pelvis")
    swayed = edit("sway", "rig").apply(walk)
    moved = subject.positions(swayed)[:, head] - subject.positions(walk)[:, head]
    heading = walk.root().heading
    left = np.column_stack([np.cos(heading), np.zeros_like(heading), -np.sin(heading)])
    toward_left = np.sum(moved * left, axis=1)
    reach = walk.values[:, walk.column("leg_l_ik.tz")]
    falling = np.r_[np.diff(reach), 0.0] < 0  # the left foot going back: it bears the weight
    mid_stance = falling & (np.abs(reach - reach.mean()) < 3.0)
    assert mid_stance.sum() >= 2 and toward_left[mid_stance].min() > 1.5  # cm to the left
    hips = subject.positions(swayed)[:, pelvis] - subject.positions(walk)[:, pelvis]
    assert np.abs(hips).max() < 1e-9
    assert np.abs(edit("sway", "rig").apply(idle).values - idle.values).max() < 1e-12
    assert np.array_equal(edit("sway", "rig", amount=0.0).apply(walk).values, walk.values)
    _, track = cmu
    swayed = edit("sway", "skeleton").apply(track, CM)
    changed = np.flatnonzero(np.any(swayed.values != track.values, axis=0))
    assert {track.channels[c].rsplit(".", 1)[0] for c in changed} == {"lowerback", "Chest"}
    zero = edit("sway", "skeleton", amount=0.0).apply(track, CM)
    np.testing.assert_allclose(zero.values, track.values, atol=1e-12)


def test_jog_is_faster_with_longer_strides_and_bent_elbows(biped, cmu):
    _, _, walk, idle = biped
    jog = edit("jog", "rig").apply(walk)
    walking = edit("jog", "rig").walking(walk, 1.0)
    assert walking[2:].min() > 0.999  # the Walk walks throughout (its first step is short)
    np.testing.assert_allclose(jog.values[:, 0], (1.0 - 0.3 * walking) * walk.values[:, 0])
    before, after = walk.root(), jog.root()
    distance = np.hypot(after.x[-1] - after.x[0], after.z[-1] - after.z[0])
    speed = distance / after.time[-1]
    old_speed = np.hypot(before.x[-1] - before.x[0], before.z[-1] - before.z[0]) / before.time[-1]
    assert speed == pytest.approx(2.0 * old_speed, rel=0.02)  # 1.4 / 0.7
    reach = walk.column("leg_l_ik.tz")
    assert np.ptp(jog.values[:, reach]) == pytest.approx(1.4 * np.ptp(walk.values[:, reach]))
    elbow = walk.column("forearm_l_fk.ry")
    assert np.median(jog.values[:, elbow] - walk.values[:, elbow]) == pytest.approx(-0.5, abs=0.01)
    assert np.abs(edit("jog", "rig").apply(idle).values - idle.values).max() < 1e-12  # standing
    unit = {
        "operations": {
            m: [dict(op, **({"gain": 1.0} if "gain" in op else {"amount": 0.0})) for op in ops]
            for m, ops in config("jog")["operations"].items()
        }
    }
    assert np.array_equal(Edit.from_config("jog", unit, "rig").apply(walk).values, walk.values)
    _, track = cmu
    jogged = edit("jog", "skeleton").apply(track, CM)
    assert jogged.root().time[-1] < 0.85 * track.root().time[-1]
    np.testing.assert_allclose(
        Edit.from_config("jog", unit, "skeleton").apply(track, CM).values, track.values, atol=1e-12
    )
