"""Control curves written as keyframes into a .blend and read back by Blender."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rigmap.rigs.base import Control, ControlTable, Pose, Rig
from rigmap.rigs.blender import export_blend, read_blend_animation
from rigmap.rigs.blender.rigify import build_rigify_human

pytestmark = [
    pytest.mark.blender,
]


@pytest.fixture(scope="module")
def human():
    rig = build_rigify_human(workers=1)
    yield rig
    rig.close()


def animated_controls(rig, frames, rng):
    """A small clip: the used controls moving smoothly (cm, radians, factors)."""
    Y = rig.default_controls(len(frames))
    used = rig.controls.used_indices
    half = (rig.controls.upper[used] - rig.controls.lower[used]) / 2
    phase = rng.uniform(0, 2 * np.pi, size=len(used))
    wave = np.sin(np.asarray(frames)[:, None] * 0.4 + phase)
    Y[:, used] += 0.2 * half * wave
    return np.clip(Y, rig.controls.lower, rig.controls.upper)  # keys are clamped to the range


def test_keyed_file_plays_back_the_same_values_and_pose(human, tmp_path):
    frames = [1, 2, 3, 5, 8]
    Y = animated_controls(human, frames, np.random.default_rng(0))
    table = pd.DataFrame(Y[:, human.controls.used_indices], columns=human.used_controls)
    table.insert(0, "frame", frames)
    out = export_blend(human, table, tmp_path / "clip.blend")
    assert out.is_file() and out.stat().st_size > 10_000
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp left

    played, pose = read_blend_animation(human, out, frames=frames)
    assert played["frame"].tolist() == frames
    keyed = played[human.used_controls].to_numpy()
    scale = np.maximum(np.abs(Y[:, human.controls.used_indices]), 1.0)
    np.testing.assert_allclose(keyed, Y[:, human.controls.used_indices], atol=1e-5 * scale.max())
    unkeyed = [n for n in human.control_names if n not in set(human.used_controls)]
    np.testing.assert_allclose(
        played[unkeyed].to_numpy(),
        human.default_controls(len(frames))[:, [human.controls.index(n) for n in unkeyed]],
        atol=1e-6,
    )
    expected = human.pose(Y)
    np.testing.assert_allclose(pose.positions, expected.positions, atol=1e-3)  # cm
    np.testing.assert_allclose(pose.cog, expected.cog, atol=1e-3)
    assert np.ptp(pose.positions[:, :, 2], axis=0).max() > 1.0  # the clip really moves

    between, _ = read_blend_animation(human, out, frames=[4])  # interpolated, not keyed
    low, high = sorted(Y[2:4, human.controls.index("hand_ik.L.tx")])
    assert low - 1.0 <= between["hand_ik.L.tx"].iloc[0] <= high + 1.0


def test_default_frames_are_the_scene_range(human, tmp_path):
    table = pd.DataFrame({"frame": [10, 12], "torso.tz": [0.0, 5.0]})
    out = export_blend(human, table, tmp_path / "range.blend")
    played, pose = read_blend_animation(human, out)
    assert played["frame"].tolist() == [10, 11, 12]
    assert played["torso.tz"].iloc[2] == pytest.approx(5.0, abs=1e-4)
    assert pose.cog[2, 1] - pose.cog[0, 1] == pytest.approx(5.0, abs=1e-3)  # cm, up (Y)


@pytest.mark.parametrize(
    ("table", "message"),
    [
        (pd.DataFrame({"torso.tz": [0.0]}), "no 'frame' column"),
        (pd.DataFrame({"frame": [1], "torso.tzz": [0.0]}), r"\['torso.tzz'\] are not controls"),
        (pd.DataFrame({"frame": [1, 2], "torso.tz": [0.0, np.nan]}), "row 1, column 'torso.tz'"),
        (pd.DataFrame({"frame": [1, 1], "torso.tz": [0.0, 1.0]}), "repeats frames"),
        (pd.DataFrame({"frame": [1]}), "no control to key"),
    ],
)
def test_bad_tables_are_refused_before_anything_is_written(human, tmp_path, table, message):
    with pytest.raises(ValueError, match=message):
        export_blend(human, table, tmp_path / "bad.blend")
    assert not list(tmp_path.iterdir())


class _PlainRig(Rig):
    def __init__(self):
        self.name = "plain"
        self.controls = ControlTable([Control("a", "scalar", 0.0, -1.0, 1.0, True, "g")])
        self.joint_names = ["j"]

    def _pose(self, Y):
        return Pose(
            np.zeros((len(Y), 1, 3)), np.zeros((len(Y), 3)), np.tile(np.eye(3), (len(Y), 1, 1))
        )


def test_only_blender_rigs_can_be_exported(tmp_path):
    with pytest.raises(TypeError, match="not a Blender rig"):
        export_blend(_PlainRig(), pd.DataFrame({"frame": [1], "a": [0.0]}), tmp_path / "x.blend")


def test_cli_export_blend_writes_the_file(human, tmp_path, capsys):
    from rigmap.cli import main

    Y = animated_controls(human, [1, 4], np.random.default_rng(1))
    table = pd.DataFrame(Y[:, human.controls.used_indices], columns=human.used_controls)
    table.insert(0, "frame", [1, 4])
    controls = tmp_path / "predicted.parquet"
    table.to_parquet(controls)
    out = tmp_path / "result.blend"
    assert (
        main(
            [
                "export-blend",
                "--rig",
                "rigify_human",
                "--controls",
                str(controls),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    played, _ = read_blend_animation(human, out, frames=[1, 4])
    np.testing.assert_allclose(
        played[human.used_controls].to_numpy(), Y[:, human.controls.used_indices], atol=1e-3
    )
    assert (
        main(
            [
                "export-blend",
                "--rig",
                "rigify_human",
                "--controls",
                str(tmp_path / "missing.parquet"),
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "missing.parquet does not exist" in capsys.readouterr().err


def test_the_cli_keys_one_clip_of_rigmaps_own_controls_table(human, tmp_path, capsys):
    """``predicted_controls.parquet`` (clip, frame, controls) exports with ``--clip``."""
    from rigmap.cli import main

    rng = np.random.default_rng(2)
    tables = []
    for clip, frames in (("Walk", [1, 2, 3]), ("Jump", [1, 2])):
        Y = animated_controls(human, frames, rng)
        table = pd.DataFrame(Y[:, human.controls.used_indices], columns=human.used_controls)
        table.insert(0, "frame", frames)
        table.insert(0, "clip", clip)
        tables.append(table)
    path = tmp_path / "predicted_controls.parquet"
    pd.concat(tables).to_parquet(path)
    out = tmp_path / "jump.blend"
    args = ["export-blend", "--rig", "rigify_human", "--controls", str(path), "--out", str(out)]
    assert main(args) == 2
    assert "holds 2 clips ['Walk', 'Jump']: pick one with --clip NAME" in capsys.readouterr().err
    assert not out.exists()
    assert main([*args, "--clip", "Jump"]) == 0
    played, _ = read_blend_animation(human, out, frames=[1, 2])
    expected = tables[1][human.used_controls].to_numpy()
    np.testing.assert_allclose(played[human.used_controls].to_numpy(), expected, atol=1e-4)
