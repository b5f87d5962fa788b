"""rigmap edits learn / apply on an artist's own example pairs (real CMU subject-07 walks).

The "artist's edit" is a real transformation of the source clip through its BVH channels:
both upper arms (``LeftArm``/``RightArm``) raised by a fixed 30° turn of their local
rotations (ours). It is learned on about three walk cycles of one take (07_05, frames
40:475 at 120 fps) and applied to other takes of the same subject.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cli_errors import fails_in_one_line
from rigmap.animation import read_bvh
from rigmap.animation.bvh import ROTATION_CHANNELS
from rigmap.animation.bvh_write import write_bvh
from rigmap.app.edits import load_settings
from rigmap.cli import main
from rigmap.edits.artist import MODEL_STEM
from rigmap.edits.pairs import feature_joints, fixed_rate, pair_scale, read_clip, read_pair
from rigmap.edits.propagation import EditModel, save_model
from rigmap.edits.study import weights_from

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
TRAIN, FRAMES = "cmu_07_05.bvh", "40:475"  # about three walk cycles of a 0.94 m/s walk
CM_PER_UNIT = 5.64  # the CMU conversions' unit (../shared/mocap/README.md: about 0.0564 m)


def arms_raised(motion, degrees: float = 30.0):
    """Both upper arms turned ``degrees`` about their parent's z axis (opposite sides
    opposite ways), written back as each joint's own Euler channels."""
    values = motion.values.copy()
    for joint, sign in (("LeftArm", 1.0), ("RightArm", -1.0)):
        j = motion.joint_index(joint)
        names, columns = motion.channels[j], motion.channel_slices()[j]
        rotation = [k for k, c in enumerate(names) if c in ROTATION_CHANNELS]
        order = "".join(names[k][0] for k in rotation).upper()
        index = [columns.start + k for k in rotation]
        old = Rotation.from_euler(order, values[:, index], degrees=True)
        new = Rotation.from_euler("z", sign * degrees, degrees=True) * old
        values[:, index] = new.as_euler(order, degrees=True)
    return replace(motion, values=values)


def edited_copy(name: str, folder: Path, edit=arms_raised) -> Path:
    path = folder / f"{Path(name).stem}_edited.bvh"
    write_bvh(edit(read_bvh(MOCAP / name)), path)
    return path


def relative_positions(motion) -> np.ndarray:
    p = motion.global_positions() * CM_PER_UNIT
    return p - p[:, :1]


@pytest.fixture(scope="module")
def learned(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pairs")
    assert (MOCAP / TRAIN).is_file(), (
        f"{MOCAP / TRAIN} is missing: the clips ship in ../shared/mocap"
    )
    edited = edited_copy(TRAIN, folder)
    model = folder / "model"
    argv = [
        "edits",
        "learn",
        "--source",
        str(MOCAP / TRAIN),
        "--edited",
        str(edited),
        "--frames",
        FRAMES,
        "--out",
        str(model),
    ]
    assert main(argv) == 0
    return folder, model


def test_learned_edit_beats_copying_the_source_on_other_takes(learned, tmp_path, capsys):
    _, model = learned
    clips = tmp_path / "clips"
    clips.mkdir()
    takes = ("cmu_07_06.bvh", "cmu_07_12.bvh", "cmu_08_04.bvh")  # 07_12: brisk, a glitch
    for name in takes:
        (clips / name).symlink_to(MOCAP / name)
    out = tmp_path / "out"
    argv = ["edits", "apply", "--model", str(model), "--input", str(clips), "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "cmu_07_12.bvh: glitch frames [1]" in printed and "repaired" in printed
    for name in takes:
        source = read_bvh(MOCAP / name)
        result = read_bvh(out / name)
        assert result.n_frames == source.n_frames - 1  # the added T-pose at frame 0 cut
        truth = relative_positions(arms_raised(source))[1:]
        copied = relative_positions(source)[1:]
        got = relative_positions(result)
        keep = slice(3, None)  # past the repaired glitch of 07_12 (file frame 1)
        error = np.mean(np.sum((got - truth) ** 2, axis=2)[keep])
        source_error = np.mean(np.sum((copied - truth) ** 2, axis=2)[keep])
        print(name, "edit error cm²", error, "copying the source", source_error)
        assert error < 0.25 * source_error, (name, error, source_error)


def test_a_written_clip_reads_back_to_the_same_joints(learned, tmp_path):
    _, model = learned
    out = tmp_path / "out"
    assert (
        main(
            [
                "edits",
                "apply",
                "--model",
                str(model),
                "--input",
                str(MOCAP / "cmu_07_01.bvh"),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    from rigmap.edits.representation import TargetTrack
    from rigmap.edits.skeleton_mode import Skeleton, skeleton_positions

    with np.load(out / "cmu_07_01.npz", allow_pickle=False) as stored:
        track = TargetTrack(
            tuple(str(c) for c in stored["channels"]),
            stored["values"],
            float(stored["fps"]),
            tuple(float(v) for v in stored["start"]),
        )
    written = read_bvh(out / "cmu_07_01.bvh")
    expected = skeleton_positions(track, Skeleton.of(written)) * CM_PER_UNIT
    assert np.abs(written.global_positions() * CM_PER_UNIT - expected).max() < 1e-4
    assert written.joint_names == read_bvh(MOCAP / "cmu_07_01.bvh").joint_names
    assert abs(written.frame_time - read_bvh(MOCAP / "cmu_07_01.bvh").frame_time) < 1e-9
    # another --fps: the same edited motion resampled, every other frame at 60 fps
    slow = tmp_path / "slow"
    assert (
        main(
            [
                "edits",
                "apply",
                "--model",
                str(model),
                "--input",
                str(MOCAP / "cmu_07_01.bvh"),
                "--out",
                str(slow),
                "--fps",
                "60",
            ]
        )
        == 0
    )
    half = read_bvh(slow / "cmu_07_01.bvh")
    assert abs(half.frame_time - 1 / 60) < 1e-9 and half.n_frames == (written.n_frames + 1) // 2
    at = written.global_positions()[::2][: half.n_frames] * CM_PER_UNIT
    assert np.abs(half.global_positions() * CM_PER_UNIT - at).max() < 0.5


def test_a_timing_track_is_resampled_to_a_fixed_rate():
    """Δt × 1.5 on every frame: at the clip's own rate 1.5 times as many frames, the root
    on the same path, each pose where the slowed clip has it at that time."""
    clip = read_clip(MOCAP / "cmu_07_06.bvh")
    track = clip.track
    slower = track.values.copy()
    slower[:, 0] *= 1.5
    result = fixed_rate(track.with_values(slower), track.fps)
    assert result.n_frames == round(1.5 * (track.n_frames - 1)) + 1
    assert np.allclose(result.values[:, 0], 1.0 / track.fps)
    before, after = track.root(), result.root()
    assert abs(after.x[-1] - before.x[-1]) < 1e-6 and abs(after.z[-1] - before.z[-1]) < 1e-6
    # output frame 3k is input frame 2k: the same pose
    assert np.allclose(result.values[::3, 4:], track.values[::2, 4:][: len(result.values[::3])])


def test_a_learned_timing_edit_yields_a_longer_clip_at_the_same_rate(tmp_path):
    """An edit that makes every frame last 1.5 times as long, learned on the whole take and
    applied to it by the command: written at the source's rate, about 1.5 times longer."""
    pair = read_pair(MOCAP / TRAIN, MOCAP / TRAIN)
    source = pair.source
    slower = source.track.values.copy()
    slower[:, 0] *= 1.5
    model = EditModel(
        feature_joints(source.motion), weights_from(load_settings()["weights"]), residual=True
    )
    model.fit([(source.source(), source.track.with_values(slower))], pair_scale([source.track]))
    save_model(model, tmp_path / "slow" / f"{MODEL_STEM}.npz")
    out = tmp_path / "out"
    assert (
        main(
            [
                "edits",
                "apply",
                "--model",
                str(tmp_path / "slow"),
                "--input",
                str(MOCAP / TRAIN),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    given, result = read_bvh(MOCAP / TRAIN), read_bvh(out / TRAIN)
    ratio = (result.n_frames - 1) / (given.n_frames - 2)  # the T-pose cut from the input
    print("timing ratio", ratio)
    assert abs(ratio - 1.5) < 0.03, ratio
    assert abs(result.frame_time - given.frame_time) < 1e-9


def test_a_glitch_frame_is_named_and_repaired_or_refused(tmp_path, capsys):
    edited = edited_copy("cmu_07_12.bvh", tmp_path)
    pair = read_pair(MOCAP / "cmu_07_12.bvh", edited, (0, 200))
    notes = " ".join(pair.source.notes)
    assert "glitch frames [1]" in notes and "repaired" in notes and "T-pose" in notes
    # file frame 1 is the clip's frame 0 after the T-pose cut: it and the next are no example
    assert not pair.examples[0] and not pair.examples[1] and pair.examples[2:].all()
    repaired = pair.source.motion.values[0]
    assert np.abs(repaired).max() > 0
    # rebuilt from captured motion only: frame 2 held, not halfway to the T-pose at frame 0
    # (halfway put the root 2 m from where the walk starts: lean_back's speed gate read it)
    raw = read_bvh(MOCAP / "cmu_07_12.bvh").values
    np.testing.assert_allclose(repaired, raw[2], atol=1e-9)
    with pytest.raises(ValueError, match=r"cmu_07_12\.bvh: frames \[1\] .* glitches"):
        read_clip(MOCAP / "cmu_07_12.bvh", glitch="refuse")
    # learned by the command: the output says what was repaired and left out
    argv = [
        "edits",
        "learn",
        "--source",
        str(MOCAP / "cmu_07_12.bvh"),
        "--edited",
        str(edited),
        "--out",
        str(tmp_path / "model"),
    ]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "glitch frames [1]" in printed and "frames [1, 2] (from 0) left out" in printed


def test_bad_pairs_are_one_line_errors_and_write_nothing(tmp_path, capsys):
    source = read_bvh(MOCAP / TRAIN)
    shorter = tmp_path / "shorter.bvh"
    write_bvh(replace(arms_raised(source), values=source.values[:-10].copy()), shorter)
    other = MOCAP / "cmu_131_01_walk.bvh"
    with_nan = tmp_path / "with_nan.bvh"
    from rigmap.animation.bvh_write import bvh_text

    lines = bvh_text(arms_raised(source)).splitlines()
    row = lines.index("MOTION") + 3 + 100  # frame 100's channel values
    lines[row] = " ".join(["nan", *lines[row].split()[1:]])
    with_nan.write_text("\n".join(lines) + "\n")
    glitchy = edited_copy("cmu_07_12.bvh", tmp_path)
    out = tmp_path / "model"
    cases = [
        ([str(MOCAP / TRAIN), str(shorter)], ["shorter.bvh", "frames"]),
        ([str(MOCAP / TRAIN), str(other)], ["cmu_131_01_walk.bvh", "skeleton"]),
        (
            [str(MOCAP / TRAIN), str(with_nan)],
            ["with_nan.bvh", f"line {row + 1}", "not a finite number"],
        ),
        (
            [str(MOCAP / "cmu_07_12.bvh"), str(glitchy), "--glitch", "refuse"],
            ["cmu_07_12.bvh", "[1]", "glitch"],
        ),
        ([str(MOCAP / TRAIN), str(MOCAP / TRAIN), "--frames", "400:900"], ["--frames 400:900"]),
    ]
    for (src, edited, *rest), words in cases:
        argv = ["edits", "learn", "--source", src, "--edited", edited, *rest, "--out", str(out)]
        fails_in_one_line(argv, capsys, *words)
        assert not out.exists()


def test_apply_checks_every_clip_before_writing_any(learned, tmp_path, capsys):
    _, model = learned
    clips = tmp_path / "clips"
    clips.mkdir()
    (clips / "a_walk.bvh").symlink_to(MOCAP / "cmu_07_06.bvh")
    (clips / "b_other_skeleton.bvh").symlink_to(MOCAP / "cmu_131_02_walk.bvh")
    out = tmp_path / "out"
    argv = ["edits", "apply", "--model", str(model), "--input", str(clips), "--out", str(out)]
    fails_in_one_line(argv, capsys, "b_other_skeleton.bvh")
    assert not out.exists()
    fails_in_one_line(["edits", "apply", "--input", str(clips)], capsys, "--model")
    fails_in_one_line(
        ["edits", "apply", "--model", str(tmp_path / "none"), "--input", str(clips)], capsys, "none"
    )


def _frames_file(motion, start: int, stop: int, path: Path) -> Path:
    write_bvh(replace(motion, values=motion.values[start:stop].copy()), path)
    return path


def test_a_fix_handed_in_as_a_file_is_learned_and_the_next_frames_suggested(
    learned, tmp_path, capsys
):
    import shutil

    model = tmp_path / "model"
    shutil.copytree(learned[1], model)
    clip = MOCAP / "cmu_07_06.bvh"
    truth = arms_raised(read_bvh(clip))
    fixed = _frames_file(truth, 100, 160, tmp_path / "fixed.bvh")

    def error_on_fixed_frames(out: Path) -> float:
        assert (
            main(["edits", "apply", "--model", str(model), "--input", str(clip), "--out", str(out)])
            == 0
        )
        got = relative_positions(read_bvh(out / clip.name))[99:159]  # file frames 100:160
        return float(np.mean(np.sum((got - relative_positions(truth)[100:160]) ** 2, axis=2)))

    before = error_on_fixed_frames(tmp_path / "before")
    capsys.readouterr()
    argv = [
        "edits",
        "fix",
        "--model",
        str(model),
        "--source",
        str(clip),
        "--fixed",
        str(fixed),
        "--frames",
        "100:160",
        "--suggest",
        "2",
    ]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    suggested = [line for line in printed.splitlines() if line.startswith("fix next: frames")]
    assert len(suggested) == 2, printed
    for line in suggested:
        start, stop = (int(v) for v in line.split()[3].split(":"))
        assert 1 <= start < stop <= 418 and (stop <= 100 or start >= 160), line
    assert (model / "fixes" / "fix_0.bvh").is_file()
    after = error_on_fixed_frames(tmp_path / "after")
    with capsys.disabled():
        print("error on the fixed frames, cm²: before", before, "after", after)
    assert after < 0.5 * before
    # a fix outside the clip, or of the wrong length: one line, the model folder unchanged
    stored = {p.name: p.read_bytes() for p in model.iterdir() if p.is_file()}
    bad = [("400:460", fixed, "outside"), ("100:150", fixed, "60 frames")]
    for frames, path, word in bad:
        argv = [
            "edits",
            "fix",
            "--model",
            str(model),
            "--source",
            str(clip),
            "--fixed",
            str(path),
            "--frames",
            frames,
        ]
        fails_in_one_line(argv, capsys, word)
        assert {p.name: p.read_bytes() for p in model.iterdir() if p.is_file()} == stored
        assert sorted(p.name for p in (model / "fixes").iterdir()) == ["fix_0.bvh"]
    # a second fix, at the first suggestion: the refit re-reads the first from the folder
    start, stop = (int(v) for v in suggested[0].split()[3].split(":"))
    second = _frames_file(truth, start, stop, tmp_path / "second.bvh")
    argv = [
        "edits",
        "fix",
        "--model",
        str(model),
        "--source",
        str(clip),
        "--fixed",
        str(second),
        "--frames",
        f"{start}:{stop}",
    ]
    assert main(argv) == 0
    import json

    fixes = json.loads((model / "learned.json").read_text())["fixes"]
    assert [f["file"] for f in fixes] == ["fixes/fix_0.bvh", "fixes/fix_1.bvh"]
    assert read_bvh(model / "fixes" / "fix_1.bvh").n_frames == stop - start


def test_a_fix_over_a_capture_glitch_is_rebuilt_said_and_not_learned(learned, tmp_path, capsys):
    """07_12's file frame 1 is all zeros, so the artist's edit of it (the arms turned, the
    root still at the origin) corrects nothing: not a glitch by itself, it would teach a
    jump of metres. Handed in over it, the fix's frame is rebuilt from its neighbours, said,
    and kept out of the examples; the refit still carries the edit."""
    import json
    import shutil

    model = tmp_path / "model"
    shutil.copytree(learned[1], model)
    clip = MOCAP / "cmu_07_12.bvh"
    truth = arms_raised(read_bvh(clip))
    fixed = _frames_file(truth, 1, 41, tmp_path / "fixed.bvh")
    assert np.abs(read_bvh(fixed).values[0]).max() > 0  # the arms' turn: no glitch by itself
    argv = ["edits", "fix", "--model", str(model), "--source", str(clip), "--fixed", str(fixed)]
    assert main([*argv, "--frames", "1:41"]) == 0
    printed = capsys.readouterr().out
    assert "frames [1] of" in printed and "rebuilt from its neighbouring frames" in printed
    (entry,) = json.loads((model / "learned.json").read_text())["fixes"]
    assert entry["left_out"] == [1] and "capture glitches" in entry["notes"][0]
    stored = read_bvh(model / entry["file"]).values
    np.testing.assert_allclose(stored[0], stored[1], atol=1e-9)  # held from frame 2
    out = tmp_path / "applied"
    assert (
        main(["edits", "apply", "--model", str(model), "--input", str(clip), "--out", str(out)])
        == 0
    )
    got = relative_positions(read_bvh(out / clip.name))[1:]  # file frames 2.. (captured)
    want, copy = (relative_positions(m)[2:] for m in (truth, read_bvh(clip)))
    error, copying = (float(np.mean(np.sum((a - want) ** 2, axis=2))) for a in (got, copy))
    with capsys.disabled():
        print("07_12 after a fix over its glitch, cm²:", error, "copying:", copying)
    assert error < 0.1 * copying
