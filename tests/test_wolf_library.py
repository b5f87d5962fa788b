"""The wolf's motion library: the dog's motions re-keyed onto Rigify's wolf (Blender).

Needs the Blender worker environment (the wolf's control table comes from Blender);
the few poses evaluated here take a second.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.animation.library import build_clip, build_clips, build_corpus, motion_library
from rigmap.animation.library import wolf as wolf_library
from rigmap.animation.library.rekey import rest_value
from rigmap.rigs import load

pytestmark = [
    pytest.mark.blender,
]
WOLF = "rigify_wolf"
PAWS = ("DEF-toe.L", "DEF-toe.R", "DEF-front_toe.L", "DEF-front_toe.R")


@pytest.fixture(scope="module")
def wolf():
    return load(WOLF)


@pytest.fixture(scope="module")
def corpora(wolf):
    return {split: build_corpus(wolf, split, seed=0) for split in ("train", "test")}


def test_same_seed_same_bytes_other_seed_other_takes(wolf, corpora, tmp_path):
    a = corpora["train"].write(tmp_path / "a.parquet").read_bytes()
    b = build_corpus(wolf, "train", seed=0).write(tmp_path / "b.parquet").read_bytes()
    other = build_corpus(wolf, "train", seed=3)
    assert a == b
    assert other.write(tmp_path / "c.parquet").read_bytes() != a
    # another take: other timing and other key values (the walk's stride)
    frames_0 = [c["frames"] for c in corpora["train"].metadata["clips"]]
    assert frames_0 != [c["frames"] for c in other.metadata["clips"]]
    travel = [c.clip_table("Walk")["torso.ty"].max() for c in (corpora["train"], other)]
    assert travel[0] != pytest.approx(travel[1])


def test_keys_only_used_controls_and_maps_every_used_control(wolf, corpora):
    used = set(wolf.used_controls)
    keyed = {control for split in ("train", "test") for clip in build_clips(WOLF, split, seed=0)
             for control in clip.controls}  # fmt: skip
    assert keyed <= used, sorted(keyed - used)
    mapped = wolf_library.wolf_controls()
    assert len(mapped) == len(set(mapped)), "a wolf control is mapped twice"
    assert set(mapped) == used
    values = corpora["train"].values()
    assert (values.std(axis=0) > 1e-9).all()


def test_the_root_keys_ground_placement_only(wolf, corpora):
    """root.tx, root.ty slide the wolf over the ground, root.rz turns it about the vertical."""
    root = [c for c in wolf.used_controls if c.startswith("root.")]
    assert root == ["root.tx", "root.ty", "root.rz"]
    c = wolf.controls.index
    Y = wolf.default_controls(4)
    Y[1, c("root.tx")] = 10.0  # cm
    Y[2, c("root.ty")] = -20.0  # cm
    Y[3, c("root.rz")] = 0.5  # rad
    pose = wolf.pose(Y)
    world = pose.positions + pose.cog[:, None, :]
    np.testing.assert_allclose(world[1:, :, 1], world[[0, 0, 0], :, 1], atol=1e-3)  # heights
    np.testing.assert_allclose(world[1] - world[0], [[10.0, 0.0, 0.0]] * wolf.n_joints, atol=1e-3)
    np.testing.assert_allclose(world[2] - world[0], [[0.0, 0.0, 20.0]] * wolf.n_joints, atol=1e-3)
    turn = np.array([[np.cos(0.5), 0, np.sin(0.5)], [0, 1, 0], [-np.sin(0.5), 0, np.cos(0.5)]])
    np.testing.assert_allclose(world[3], world[0] @ turn.T, atol=1e-3)  # nose toward +X (left)
    for control in root:
        assert corpora["train"].table[control].std() > 0


def test_rest_values_the_mapping_assumes_are_the_rigs(wolf):
    dog = load("quadruped")
    for channel in wolf_library.CHANNELS:
        assert wolf.controls[channel.target].default == pytest.approx(
            rest_value(channel.target, wolf_library.WOLF_DEFAULTS)
        ), channel.target
        for term in channel.terms:
            assert dog.controls[term.source].default == pytest.approx(
                rest_value(term.source, wolf_library.DOG_DEFAULTS)
            ), term.source
    for channel in wolf_library.SETTLE_CHANNELS:
        control = wolf.controls[channel.target]
        assert control.lower <= channel.centre <= control.upper


def test_test_clips_are_held_out_and_larger_and_faster(corpora):
    train, test = corpora["train"].table, corpora["test"].table
    assert set(corpora["test"].clip_names) == {
        "Jumping & Playing",
        "Turning & Galloping",
        "Begging Excitedly",
    }
    assert not set(corpora["test"].clip_names) & set(corpora["train"].clip_names)

    def fastest(table, control):
        return max(np.abs(np.diff(g[control].to_numpy())).max() for _, g in table.groupby("clip"))

    for control in ("root.ty", "root.rz", "torso.tz", "torso.rx"):  # travel, turn, leap, pitch
        assert fastest(test, control) > 1.5 * fastest(train, control), control
    assert np.abs(test["root.rz"]).max() > 5 * np.abs(train["root.rz"]).max()


def test_walking_paws_are_planted_on_the_floor(wolf):
    """The dog's plants survive the re-keying: paws touch the floor and do not slide there."""
    motion = motion_library(WOLF).find("Walk")[1]
    clip = build_clip(WOLF, motion, seed=0)
    pose = wolf.pose(clip.evaluate(wolf.control_names, wolf.controls.defaults))
    world = pose.positions + pose.cog[:, None, :]
    lowest = world[:, :, 1].min()
    assert lowest > 0.0, f"a joint goes {lowest:.2f} cm under the floor"
    for name in PAWS:
        paw = world[:, wolf.joint_names.index(name)]
        floor = paw[:, 1].min()
        assert floor < 5.0  # cm: the toe joint's height when the paw stands
        down = paw[:, 1] < floor + 0.2
        assert 0.6 < down.mean() < 0.95, name  # planted most of the time, and it steps
        starts = np.flatnonzero(np.diff(np.concatenate([[0], down.astype(int)])) == 1)
        ends = np.flatnonzero(np.diff(np.concatenate([down.astype(int), [0]])) == -1)
        for start, end in zip(starts, ends, strict=True):
            slide = np.linalg.norm(paw[start : end + 1][:, [0, 2]] - paw[start][[0, 2]], axis=1)
            assert slide.max() < 0.5, (name, start, slide.max())  # cm


def test_torso_rotation_turns_the_wolf_axes():
    """Euler XYZ about the torso's own axes (X left, Y back, Z up) in rigmap's axes."""
    pitch = wolf_library.torso_rotation(0.3, 0.0, 0.0)[0]
    nose = pitch @ np.array([0.0, 0.0, 1.0])
    assert nose[1] < 0  # rx > 0: nose down
    yaw = wolf_library.torso_rotation(0.0, 0.0, 0.3)[0]
    assert (yaw @ np.array([0.0, 0.0, 1.0]))[0] > 0  # rz > 0: nose to the left (+X)
    roll = wolf_library.torso_rotation(0.0, 0.3, 0.0)[0]
    assert (roll @ np.array([0.0, 1.0, 0.0]))[0] > 0  # ry > 0: back rolls to the left
    R = wolf_library.torso_rotation([0.2, -1.0], [0.4, 0.1], [-0.7, 2.0])
    np.testing.assert_allclose(
        R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
