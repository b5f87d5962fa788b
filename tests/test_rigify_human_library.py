"""Rigify's human's motion library: the biped's motions re-keyed onto its controls (Blender).

Needs the Blender worker environment (the control table and the poses come from
Blender); the clips are posed on the generated rig, a few hundred poses in all.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from blender_script import run_bpy
from rigmap.animation.library import build_clip, build_corpus, clip_rng, motion_library
from rigmap.animation.library import rigify_human as rigify_library
from rigmap.animation.library.clip_builder import ClipBuilder
from rigmap.animation.library.rekey import rest_value
from rigmap.rigs import load

pytestmark = [pytest.mark.blender]
RIG = "rigify_human"
FEET = ("DEF-foot.L", "DEF-foot.R", "DEF-toe.L", "DEF-toe.R")
#: biped joint pair → Rigify joint pair whose direction should agree
LIMBS = {
    ("upper_arm_l", "forearm_l"): ("DEF-upper_arm.L", "DEF-forearm.L"),
    ("forearm_r", "hand_r"): ("DEF-forearm.R", "DEF-hand.R"),
    ("thigh_l", "shin_l"): ("DEF-thigh.L", "DEF-shin.L"),
    ("shin_r", "foot_r"): ("DEF-shin.R", "DEF-foot.R"),
    ("foot_l", "ball_l"): ("DEF-foot.L", "DEF-toe.L"),
    ("pelvis", "neck_1"): ("DEF-spine", "DEF-spine.004"),
}


@pytest.fixture(scope="module")
def human():
    return load(RIG)


@pytest.fixture(scope="module")
def corpora(human):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a key outside a soft range warns: fail on it
        return {split: build_corpus(human, split, seed=0) for split in ("train", "test")}


def world(rig, Y):
    pose = rig.pose(Y)
    return np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]


def test_same_seed_same_bytes_other_seed_other_takes(human, corpora, tmp_path):
    a = corpora["train"].write(tmp_path / "a.parquet").read_bytes()
    b = build_corpus(human, "train", seed=0).write(tmp_path / "b.parquet").read_bytes()
    assert a == b
    other = build_corpus(human, "train", seed=3)
    assert other.write(tmp_path / "c.parquet").read_bytes() != a
    assert corpora["test"].clip_names == ["Range of Motion", "Swing Dance", "Tai Chi"]
    assert len(corpora["train"].clip_names) == 11


def test_keys_every_used_control_and_nothing_else(human, corpora):
    mapped = rigify_library.rigify_controls()
    assert len(mapped) == len(set(mapped)), "a Rigify control is mapped twice"
    assert set(mapped) == set(human.used_controls)
    for split, corpus in corpora.items():
        for clip in corpus.clip_names:
            keyed = set(build_clip(RIG, motion_library(RIG).find(clip)[1], seed=0).controls)
            assert keyed <= set(human.used_controls), (split, clip)
    values = corpora["train"].values()
    still = [n for n, s in zip(human.used_controls, values.std(axis=0), strict=True) if s < 1e-9]
    assert not still, f"used controls that never move in training: {still}"


def test_every_key_is_inside_the_soft_ranges(human, corpora):
    used = human.controls.used_indices
    lower, upper = human.controls.lower[used], human.controls.upper[used]
    for corpus in corpora.values():
        values = corpus.values()
        assert np.isfinite(values).all()
        assert (values >= lower - 1e-9).all() and (values <= upper + 1e-9).all()


def test_rest_values_the_mapping_assumes_are_the_rigs(human):
    biped = load("biped")
    for channel in rigify_library.CHANNELS:
        assert human.controls[channel.target].default == pytest.approx(
            rest_value(channel.target, rigify_library.RIGIFY_DEFAULTS)
        ), channel.target
        for term in channel.terms:
            assert biped.controls[term.source].default == pytest.approx(
                rest_value(term.source, rigify_library.BIPED_DEFAULTS)
            ), term.source
    for channel in rigify_library.SETTLE_CHANNELS:
        control = human.controls[channel.target]
        assert control.lower <= channel.centre <= control.upper
        assert control.default == pytest.approx(
            rest_value(channel.target, rigify_library.RIGIFY_DEFAULTS)
        ), channel.target


@pytest.mark.parametrize("clip", ["Walk", "Wave", "Kick", "Tai Chi"])
def test_limbs_point_where_the_bipeds_do(human, clip):
    """One take keyed on both rigs: bones point the same way, frame by frame (posed in Blender)."""
    biped = load("biped")
    motion = motion_library("biped").find(clip)[1]
    on_rigify = ClipBuilder(clip, clip_rng(0, RIG, clip))
    on_biped = ClipBuilder(clip, on_rigify.rng)  # the stand-in the library keys first
    motion.keyframe(on_biped)
    rigify_library.BipedToRigifyHuman(on_biped.nominal_curves()).key_onto(on_rigify)
    frames = np.arange(on_biped.nominal_frames[0], on_biped.nominal_frames[-1] + 1)
    poses = []
    for rig, builder in ((biped, on_biped), (human, on_rigify)):
        Y = rig.default_controls(len(frames))
        for control, curve in builder.nominal_curves().items():
            Y[:, rig.controls.index(control)] = curve.evaluate(frames)
        poses.append(world(rig, Y))
    for (b0, b1), (r0, r1) in LIMBS.items():
        directions = []
        for rig, pose, (j0, j1) in ((biped, poses[0], (b0, b1)), (human, poses[1], (r0, r1))):
            d = pose[:, rig.joint_names.index(j1)] - pose[:, rig.joint_names.index(j0)]
            directions.append(d / np.linalg.norm(d, axis=1, keepdims=True))
        angle = np.degrees(np.arccos(np.clip((directions[0] * directions[1]).sum(1), -1, 1)))
        assert np.median(angle) < 15.0 and angle.max() < 45.0, (clip, b0, angle.max())


def stance_slides(foot: np.ndarray, tolerance: float = 0.5) -> list[float]:
    """Per stance (frames within ``tolerance`` cm of the lowest), how far it slides (cm)."""
    down = foot[:, 1] < foot[:, 1].min() + tolerance
    starts = np.flatnonzero(np.diff(np.concatenate([[0], down.astype(int)])) == 1)
    ends = np.flatnonzero(np.diff(np.concatenate([down.astype(int), [0]])) == -1)
    return [
        float(np.linalg.norm(foot[a : b + 1][:, [0, 2]] - foot[a][[0, 2]], axis=1).max())
        for a, b in zip(starts, ends, strict=True)
    ]


def test_walk_stands_on_the_floor_and_travels_forward(human):
    clip = build_clip(RIG, motion_library(RIG).find("Walk")[1], seed=0)
    pose = world(human, clip.evaluate(human.control_names, human.controls.defaults))
    feet = pose[:, [human.joint_names.index(j) for j in FEET]]
    assert pose[:, :, 1].min() > -0.5  # cm: nothing under the floor
    assert feet[:, :, 1].min() < 3.0  # cm: the toes reach it
    travel = pose[-1].mean(axis=0) - pose[0].mean(axis=0)
    assert travel[2] > 200.0 and abs(travel[0]) < 0.3 * travel[2]  # cm, forward is +Z
    # the toes are down about half the time and slide no more than the biped's own (its walk
    # slides a planted foot back at part of the root's speed), scaled to the taller body
    biped = load("biped")
    own = build_clip("biped", motion_library("biped").find("Walk")[1], seed=0)
    biped_pose = world(biped, own.evaluate(biped.control_names, biped.controls.defaults))
    biped_slide = max(stance_slides(biped_pose[:, biped.joint_names.index("ball_l")]))
    for name in ("DEF-toe.L", "DEF-toe.R"):
        toe = pose[:, human.joint_names.index(name)]
        assert 0.4 < (toe[:, 1] < toe[:, 1].min() + 0.5).mean() < 0.7, name
        slides = stance_slides(toe)
        assert len(slides) >= 3 and max(slides) < 1.5 * rigify_library.LENGTH_SCALE * biped_slide


def test_euler_angles_round_trip_without_flips():
    t = np.linspace(0.0, 1.0, 200)
    # a bend past ±π/2 about the middle axis, where the other Euler triple takes over
    steps = np.column_stack([0.3 * np.sin(6 * t), 2.0 * t, 0.2 * np.cos(4 * t)])
    for mode in ("XYZ", "YXZ"):
        R = rigify_library.euler_matrices(steps, mode)
        angles = rigify_library.matrices_to_euler(R, mode)
        np.testing.assert_allclose(rigify_library.euler_matrices(angles, mode), R, atol=1e-9)
        assert np.abs(np.diff(angles, axis=0)).max() < 1.5  # rad: no ±π jumps between rows


READ_BONES = """
import json, sys
import bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[-3])
rig = bpy.data.objects[sys.argv[-2]]
out = {}
for bone in rig.data.bones:
    m = bone.matrix_local.to_3x3()
    # rigmap axes: X = Blender X, Y = Blender Z, Z = -Blender Y
    frame = [[m[0][j] for j in range(3)], [m[2][j] for j in range(3)], [-m[1][j] for j in range(3)]]
    head = bone.head_local * 100.0
    out[bone.name] = {"frame": frame, "head": [head[0], head[2], -head[1]],
                      "mode": rig.pose.bones[bone.name].rotation_mode}
with open(sys.argv[-1], "w") as stream:
    json.dump(out, stream)
"""


def test_rest_frames_and_rotation_modes_are_the_generated_rigs(human, tmp_path):
    """The conventions the re-keying hard-codes, read back from the rig's .blend by bpy."""
    bones = run_bpy(READ_BONES, str(human.path), "rig", folder=tmp_path)
    turned = {(turn.target, turn.side) for turn in rigify_library.TURNS}
    for bone in rigify_library.REST_FRAMES_LEFT:
        for side in ("L", "R") if f"{bone}.L" in bones else (None,):
            read = bones[bone if side is None else f"{bone}.{side}"]
            expected = rigify_library.rest_frame(bone, side)
            # 5e-3: the generated right foot is 0.1° off the left one's mirror
            np.testing.assert_allclose(read["frame"], expected, atol=5e-3, err_msg=(bone, side))
            if (bone, side) in turned:
                mode = "XYZ" if read["mode"] == "QUATERNION" else read["mode"]  # the session's
                assert mode == rigify_library.ROTATION_MODES.get(bone, "XYZ"), (bone, side)
    for name, position in (("upper_arm_fk.L", rigify_library.RIGIFY_SHOULDER),
                           ("hand_ik.L", rigify_library.RIGIFY_WRIST)):  # fmt: skip
        np.testing.assert_allclose(bones[name]["head"], position, atol=0.01)
