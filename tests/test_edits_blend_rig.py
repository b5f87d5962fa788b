"""Rig mode on Blender's Rigify human (issue #40): Z-up root controls, a learned edit, and
the ``.blend`` that ``rigmap edits apply`` writes, read back through Blender.

The rig is evaluated by Blender worker processes, so the clips are short (48 frames of
the library's Walk and Idle to learn from, 60 of another Walk to apply to). The edit is
the procedural ``lean_back`` of ``conf/edit/lean_back.yaml`` on ``chest.rx``, as for the
biped in tests/test_edits_rig_pairs.py. The ``.blend`` is read back with the action
reader ``rigmap learn`` imports a user's .blend with
(:func:`rigmap.animation.blend_corpus.import_blend_corpus`): no stand-in on either side.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from rigmap.animation.blend_corpus import import_blend_corpus
from rigmap.cli import main
from rigmap.edits.features import heading_from_axis
from rigmap.edits.procedural import Edit
from rigmap.edits.representation import TargetTrack
from rigmap.edits.rig_mode import rig_controls, rig_targets
from rigmap.edits.rig_pairs import RigMode, controls_table, write_controls
from rigmap.edits.subjects import rig_clip

pytestmark = [pytest.mark.blender]

ROOT = Path(__file__).resolve().parents[1]
LEAN_BACK = Edit.from_config(
    "lean_back", yaml.safe_load((ROOT / "src/rigmap/conf/edit/lean_back.yaml").read_text()), "rig"
)
LEARN_FRAMES, APPLY_FRAMES = 48, 60


@pytest.fixture(scope="module")
def mode() -> RigMode:
    return RigMode.of("rigify_human")


def walking_turn(mode: RigMode, frames: int = 40, speed: float = 2.5, turn: float = 0.6):
    """The rest pose carried by the root: ``root.rz`` turns by ``turn`` rad over the clip,
    and each frame steps ``speed`` cm along the way the rig faces — rigmap's ``(sin h,
    cos h)`` on the ground (+Z at h = 0), Blender's ``(tx, ty) = (sin h, -cos h)``."""
    rig = mode.rig
    heading = np.linspace(0.0, turn, frames)
    tx = 5.0 + np.concatenate([[0.0], np.cumsum(speed * np.sin(heading[:-1]))])
    ty = -7.0 - np.concatenate([[0.0], np.cumsum(speed * np.cos(heading[:-1]))])
    used = np.tile(rig.controls.defaults[rig.controls.used_indices], (frames, 1))
    for name, values in zip(("root.tx", "root.ty", "root.rz"), (tx, ty, heading), strict=True):
        used[:, mode.used.index(name)] = values
    return used, heading


def test_rigify_root_controls_are_steps_and_turns_of_what_the_rig_shows(mode):
    """A walk along a turn: controls → target track → controls to 1e-9; the track's steps
    are all forward (``speed`` per frame, none sideways) and its turns sum to ``root.rz``'s;
    Blender's joint positions (rigmap's Y-up axes) are the rest pose turned by ``root.rz``
    about +Y and moved to ``(tx, -ty)``, and their heading (the thighs' axis) turns by it."""
    used, heading = walking_turn(mode)
    track = rig_targets(used, mode.channels, 24.0)
    np.testing.assert_allclose(rig_controls(track, mode.channels), used, rtol=0, atol=1e-9)
    np.testing.assert_allclose(track.values[1:, 1], 2.5, atol=1e-9)  # forward
    np.testing.assert_allclose(track.values[1:, 2], 0.0, atol=1e-9)  # sideways
    np.testing.assert_allclose(track.values[1:, 3].sum(), 0.6, atol=1e-12)
    positions = mode.subject.positions(track)
    x, z = used[:, mode.used.index("root.tx")], -used[:, mode.used.index("root.ty")]
    standing = rig_targets(used[:1].repeat(3, 0), mode.channels, 24.0)  # frame 0, heading 0
    rest = mode.subject.positions(standing)[0] - [x[0], 0.0, z[0]]
    c, s = np.cos(heading), np.sin(heading)
    turned_x = c[:, None] * rest[None, :, 0] + s[:, None] * rest[None, :, 2]
    turned_z = -s[:, None] * rest[None, :, 0] + c[:, None] * rest[None, :, 2]
    expected = np.stack(
        [turned_x + x[:, None], np.broadcast_to(rest[:, 1], turned_x.shape), turned_z + z[:, None]],
        axis=2,
    )
    gap = float(np.abs(positions - expected).max())
    joints = mode.subject.joints
    shown = heading_from_axis(positions, joints.left, joints.right)
    turned = np.unwrap(shown - shown[0])
    print(f"\nrigify walk along a turn: joints off the turned rest pose by {gap:.2g} cm")
    assert gap < 1e-3  # Blender reports positions in float32
    np.testing.assert_allclose(turned, heading, atol=1e-5)


def write_clip(mode: RigMode, used: np.ndarray, path: Path) -> Path:
    return write_controls(path, controls_table(used, mode.used))


def library_clip(mode: RigMode, motion: str, seed: int, frames: int) -> TargetTrack:
    track = rig_clip(mode.rig, mode.channels, motion, seed)
    return rig_targets(rig_controls(track, mode.channels)[:frames], mode.channels, track.fps)


def relative_cm(mode: RigMode, used: np.ndarray) -> np.ndarray:
    return mode.subject.relative_cm(rig_targets(used, mode.channels, mode.fps))


@pytest.fixture(scope="module")
def applied(mode, tmp_path_factory):
    """Learned on a Walk and an Idle (seed 0) and their lean_back; applied to another Walk."""
    folder = tmp_path_factory.mktemp("rigify_edit")
    argv = ["edits", "learn", "--rig", "rigify_human"]
    for motion in ("Walk", "Idle"):
        track = library_clip(mode, motion, 0, LEARN_FRAMES)
        name = motion.lower()
        source = write_clip(mode, rig_controls(track, mode.channels), folder / f"{name}.parquet")
        edited = rig_controls(LEAN_BACK.apply(track), mode.channels)
        edited_path = write_clip(mode, edited, folder / f"{name}_edited.parquet")
        argv += ["--source", str(source), "--edited", str(edited_path)]
    assert main([*argv, "--out", str(folder / "model")]) == 0
    held_out = library_clip(mode, "Walk", 1, APPLY_FRAMES)
    clips = folder / "clips"
    clips.mkdir()
    write_clip(mode, rig_controls(held_out, mode.channels), clips / "walk.parquet")
    out = folder / "out"
    apply = ["edits", "apply", "--model", str(folder / "model"), "--input", str(clips)]
    assert main([*apply, "--out", str(out)]) == 0
    return held_out, out, folder / "model"


def test_a_rigify_edit_is_learned_and_carried_to_another_walk(mode, applied):
    held_out, out, _ = applied
    table = pd.read_parquet(out / "walk.parquet")
    assert list(table.columns) == ["frame", *mode.used] and len(table) == APPLY_FRAMES
    got = table[list(mode.used)].to_numpy(dtype=np.float64)
    source = rig_controls(held_out, mode.channels)
    truth = rig_controls(LEAN_BACK.apply(held_out), mode.channels)
    want = relative_cm(mode, truth)
    error = float(np.mean(np.sum((relative_cm(mode, got) - want) ** 2, axis=2)))
    copying = float(np.mean(np.sum((relative_cm(mode, source) - want) ** 2, axis=2)))
    print(f"\nrigify_human walk: lean_back error cm² {error:.3f}, source {copying:.3f}")
    assert error < 0.25 * copying, (error, copying)


def test_the_written_blend_plays_back_the_parquets_controls(mode, applied):
    """The ``.blend`` beside the parquet, read back by the corpus importer: one action,
    at the output rate, keyed on every used control; Blender's own F-curve values equal the
    parquet's controls to 1e-5 on every frame and control."""
    _, out, _ = applied
    (row,) = json.loads((out / "applied.json").read_text())["clips"]
    assert row["blend"] == str(out / "walk.blend") and "no_blend" not in row
    table = pd.read_parquet(out / "walk.parquet")
    imported = import_blend_corpus(
        out / "walk.blend", armature="rig", split=False, check_determinism=False
    )
    (clip,) = imported.clips
    assert clip.name == "walk_edit" and imported.fps == 24
    assert (clip.start, clip.end) == (table["frame"].iloc[0], table["frame"].iloc[-1])
    played = imported.blender_values["walk_edit"]
    assert set(mode.used) <= set(played)
    gaps = {n: float(np.abs(np.asarray(played[n]) - table[n].to_numpy()).max()) for n in mode.used}
    worst = max(gaps, key=gaps.get)
    print(
        f"\nrigify .blend round trip: max |Blender - parquet| {gaps[worst]:.3g} ({worst!r}, "
        f"{np.abs(table[worst]).max():.1f} at most) over {len(table)} frames, {len(gaps)} controls"
    )
    for name in mode.used:
        np.testing.assert_allclose(played[name], table[name].to_numpy(), rtol=0, atol=1e-5)


def test_the_blend_is_keyed_at_the_output_rate(mode, applied, tmp_path):
    """``--fps 30``: the parquet resampled to 30 fps (75 frames for 60 at 24: the grid of
    ``representation.resample``, to the last frame's time + half a frame) and the
    ``.blend``'s scene at 30 fps, its action playing back the parquet's controls."""
    _, out, model = applied
    clip = out.parent / "clips" / "walk.parquet"
    faster = tmp_path / "faster"
    argv = ["edits", "apply", "--model", str(model), "--input", str(clip), "--out", str(faster)]
    assert main([*argv, "--fps", "30"]) == 0
    table = pd.read_parquet(faster / "walk.parquet")
    assert len(table) == len(np.arange(0.0, (APPLY_FRAMES - 1) / 24 + 0.5 / 30, 1 / 30)) == 75
    imported = import_blend_corpus(
        faster / "walk.blend", armature="rig", split=False, check_determinism=False
    )
    assert imported.fps == 30 and imported.clips[0].end == 74
    played = imported.blender_values["walk_edit"]
    for name in mode.used:
        np.testing.assert_allclose(played[name], table[name].to_numpy(), rtol=0, atol=1e-5)


def test_a_rigify_fix_is_learned(mode, applied, tmp_path):
    """``rigmap edits fix`` with a controls parquet of the true frames 20:40 of the held-out
    Walk: applied again, the model's error on those frames drops."""
    import shutil

    held_out, out, learned_model = applied
    model = tmp_path / "model"
    shutil.copytree(learned_model, model)
    clip = out.parent / "clips" / "walk.parquet"
    truth = rig_controls(LEAN_BACK.apply(held_out), mode.channels)
    start, stop = 20, 40
    fixed = write_controls(
        tmp_path / "fixed.parquet", controls_table(truth[start:stop], mode.used, start)
    )

    def error_on_fixed_frames(folder: Path) -> float:
        argv = ["edits", "apply", "--model", str(model), "--input", str(clip), "--out"]
        assert main([*argv, str(folder)]) == 0
        got = pd.read_parquet(folder / "walk.parquet")[list(mode.used)].to_numpy()
        gap = (relative_cm(mode, got) - relative_cm(mode, truth))[start:stop]
        return float(np.mean(np.sum(gap**2, axis=2)))

    before = error_on_fixed_frames(tmp_path / "before")
    fix = ["edits", "fix", "--model", str(model), "--source", str(clip), "--fixed", str(fixed)]
    assert main([*fix, "--frames", f"{start}:{stop}", "--suggest", "1"]) == 0
    after = error_on_fixed_frames(tmp_path / "after")
    print(f"\nrigify fix: error on the fixed frames cm² before {before:.3g}, after {after:.3g}")
    assert after < 0.5 * before
