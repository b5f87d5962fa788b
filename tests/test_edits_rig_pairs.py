"""rigmap edits learn / apply / fix in rig mode: controls parquets of the built-in rigs.

The "artist's edit" is the procedural ``lean_back`` of ``conf/edit/lean_back.yaml`` (the
chest pitched back by 0.25 rad per m/s of root speed), applied to clips of the rig's
motion library (:func:`rigmap.edits.subjects.rig_clip`) and written as controls parquets,
as ``rigmap map`` writes them. It is learned on a walk and a standing clip (seed 0) and
applied to other clips at another seed's variation, where the same procedural edit is
the truth the propagated edit is measured against.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from cli_errors import fails_in_one_line
from rigmap.app.edits import load_settings
from rigmap.cli import main
from rigmap.edits.artist import MODEL_STEM, new_model, read_track
from rigmap.edits.pairs import pair_scale
from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import save_model
from rigmap.edits.representation import TargetTrack, integrate_root
from rigmap.edits.rig_mode import full_controls, rig_controls, rig_targets
from rigmap.edits.rig_pairs import RigMode, controls_table, write_controls
from rigmap.edits.subjects import rig_clip
from rigmap.store import write_json_atomic

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
LEAN_BACK = Edit.from_config(
    "lean_back", yaml.safe_load((ROOT / "src/rigmap/conf/edit/lean_back.yaml").read_text()), "rig"
)
#: per rig: the examples (a walk and a stand, seed 0) and the held-out clips (seed 1). Of
#: the quadruped's library only the Trot moves the root (its Walk walks in place, its COG
#: moving), so only the Trot leans back
CLIPS = {
    "biped": (("Walk", "Idle"), ("Walk", "Walk Start Stop")),
    "quadruped": (("Trot", "Look Around"), ("Trot",)),
}


def library_controls(mode: RigMode, motion: str, seed: int) -> TargetTrack:
    return rig_clip(mode.rig, mode.channels, motion, seed)


def write_clip(mode: RigMode, track: TargetTrack, path: Path, every_control=False) -> Path:
    """The track as a controls parquet: the used controls, or (``every_control``) every
    control of the rig, the unused at their defaults, as ``rigmap map`` writes it."""
    used = rig_controls(track, mode.channels)
    if not every_control:
        return write_controls(path, controls_table(used, mode.used))
    rig = mode.rig
    values = full_controls(used, rig.controls.used_indices, rig.controls.defaults)
    return write_controls(path, controls_table(values, rig.control_names))


def relative_cm(mode: RigMode, controls: np.ndarray) -> np.ndarray:
    """Joint positions relative to the root joint (cm) of used controls."""
    track = rig_targets(controls, mode.channels, mode.fps)
    return mode.subject.relative_cm(track)


def joint_error(mode: RigMode, got: np.ndarray, want: np.ndarray, frames=slice(None)) -> float:
    """Mean squared joint distance (cm²) over ``frames``, positions relative to the root."""
    gap = (relative_cm(mode, got) - relative_cm(mode, want))[frames]
    return float(np.mean(np.sum(gap**2, axis=2)))


def read_parquet_controls(path: Path, mode: RigMode) -> tuple[np.ndarray, np.ndarray]:
    table = pd.read_parquet(path)
    assert list(table.columns) == ["frame", *mode.used]
    return table["frame"].to_numpy(), table[list(mode.used)].to_numpy(dtype=np.float64)


def learn_argv(pairs, out: Path, *rest) -> list[str]:
    argv = ["edits", "learn"]
    for source, edited in pairs:
        argv += ["--source", str(source), "--edited", str(edited)]
    return [*argv, *rest, "--out", str(out)]


def _learned(rig_name: str, folder: Path):
    mode = RigMode.of(rig_name)
    examples = []
    for k, motion in enumerate(CLIPS[rig_name][0]):
        track = library_controls(mode, motion, 0)
        # the first source as rigmap map writes it: every control, the unused at defaults
        source = write_clip(mode, track, folder / f"{k}_source.parquet", every_control=k == 0)
        edited = write_clip(mode, LEAN_BACK.apply(track), folder / f"{k}_edited.parquet")
        examples.append((source, edited))
    model = folder / "model"
    argv = learn_argv(examples, model, "--rig", rig_name, "--frames", "2:60", "--frames", "all")
    assert main(argv) == 0
    return mode, model, examples


@pytest.fixture(scope="module")
def learned_biped(tmp_path_factory):
    return _learned("biped", tmp_path_factory.mktemp("rig_pairs"))


def test_learned_model_records_its_mode_rig_and_rate(learned_biped, capsys):
    mode, model, _ = learned_biped
    learned = json.loads((model / "learned.json").read_text())
    assert (learned["mode"], learned["rig"], learned["fps"]) == ("rig", "biped", 24.0)
    idle = library_controls(mode, "Idle", 0).n_frames
    assert [p["frames"] for p in learned["pairs"]] == [[2, 60], [0, idle]]
    assert "all at their defaults" in " ".join(learned["pairs"][0]["notes"])
    assert (model / f"{MODEL_STEM}.npz").is_file() and (model / f"{MODEL_STEM}.json").is_file()


@pytest.mark.parametrize("rig_name", ["biped", "quadruped"])
def test_a_learned_rig_edit_is_carried_to_held_out_clips(rig_name, learned_biped, tmp_path, capsys):
    if rig_name == "biped":
        mode, model, _ = learned_biped
    else:
        mode, model, _ = _learned(rig_name, tmp_path / "learn")
    clips = tmp_path / "clips"
    clips.mkdir(exist_ok=True)
    truths = {}
    for motion in CLIPS[rig_name][1]:
        track = library_controls(mode, motion, 1)
        name = motion.replace(" ", "_").lower()
        write_clip(mode, track, clips / f"{name}.parquet")
        truths[name] = (rig_controls(track, mode.channels), LEAN_BACK.apply(track))
    out = tmp_path / "out"
    argv = ["edits", "apply", "--model", str(model), "--input", str(clips), "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert f"no .blend written: rig {rig_name!r} has neither a Blender file" in printed
    applied = json.loads((out / "applied.json").read_text())
    assert applied["mode"] == "rig" and applied["rig"] == rig_name
    for row in applied["clips"]:
        assert row["blend"] is None and "neither a Blender file" in row["no_blend"]
    assert not list(out.glob("*.blend"))
    for name, (source, truth_track) in truths.items():
        frames, got = read_parquet_controls(out / f"{name}.parquet", mode)
        predicted = rig_controls(read_track(out / f"{name}.npz"), mode.channels)
        np.testing.assert_allclose(got, predicted, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(frames, np.arange(len(source)))
        truth = rig_controls(truth_track, mode.channels)
        error, copying = joint_error(mode, got, truth), joint_error(mode, source, truth)
        with capsys.disabled():
            print(f"\n{rig_name} {name}: lean_back error cm² {error:.3f}, source {copying:.3f}")
        assert error < 0.25 * copying, (name, error, copying)


def test_another_output_rate_resamples_the_edited_clip(learned_biped, tmp_path):
    mode, model, _ = learned_biped
    clip = write_clip(mode, library_controls(mode, "Walk", 1), tmp_path / "walk.parquet")
    out, half = tmp_path / "out", tmp_path / "half"
    for folder, rate in ((out, []), (half, ["--fps", "12"])):
        argv = ["edits", "apply", "--model", str(model), "--input", str(clip), "--out", str(folder)]
        assert main([*argv, *rate]) == 0
    _, whole = read_parquet_controls(out / "walk.parquet", mode)
    frames, slow = read_parquet_controls(half / "walk.parquet", mode)
    (row,) = json.loads((half / "applied.json").read_text())["clips"]
    assert row["fps_in"] == 24.0 and row["fps_out"] == 12.0 and row["resampled"]
    assert len(slow) == (len(whole) + 1) // 2 and list(frames) == list(range(len(slow)))
    pose = [mode.used.index(c) for c in mode.channels.pose]
    np.testing.assert_allclose(slow[:, pose], whole[::2][:, pose], atol=1e-9)


def test_a_learned_timing_edit_gives_a_longer_clip_at_a_fixed_rate(tmp_path):
    """Every frame 1.5 times as long (the giant's Δt, §7.2): a parquet pair cannot carry
    timing, so the model is fitted here and written as learn writes it; applied by the
    command, the clip comes out at the model's 24 fps with as many frames as the predicted
    frame times cover."""
    mode = RigMode.of("biped")
    source = library_controls(mode, "Walk", 0)
    slower = source.values.copy()
    slower[:, 0] *= 1.5
    model = new_model(mode.subject.joints, load_settings())
    model.fit([(mode.subject.source(source), source.with_values(slower))], pair_scale([source]))
    folder = tmp_path / "slow"
    save_model(model, folder / f"{MODEL_STEM}.npz")
    write_json_atomic(folder / "learned.json", {**mode.summary(), "pairs": [], "fixes": []})
    held_out = library_controls(mode, "Walk", 1)
    clip = write_clip(mode, held_out, tmp_path / "walk.parquet")
    out = tmp_path / "out"
    argv = ["edits", "apply", "--model", str(folder), "--input", str(clip), "--out", str(out)]
    assert main(argv) == 0
    predicted = model.apply(mode.subject.source(held_out))
    seconds = integrate_root(predicted.values[:, :4], predicted.start).time[-1]
    expected = len(np.arange(0.0, seconds + 0.5 / 24, 1 / 24))
    frames, _ = read_parquet_controls(out / "walk.parquet", mode)
    (row,) = json.loads((out / "applied.json").read_text())["clips"]
    ratio = (len(frames) - 1) / (held_out.n_frames - 1)
    print("timing: frames", held_out.n_frames, "->", len(frames), "ratio", ratio)
    assert len(frames) == expected == row["frames_out"] and row["fps_out"] == 24.0
    assert abs(ratio - 1.5) < 0.05, ratio
    assert read_track(out / "walk.npz").fps == 24.0


def _bad_files(mode: RigMode, folder: Path, source: Path) -> list[tuple[str, list[str]]]:
    """Edited files each wrong in one way, and the words their error must hold."""
    table = pd.read_parquet(source)
    table = table[["frame", *mode.used]]
    cases = []

    def bad(name: str, changed: pd.DataFrame, *words: str) -> None:
        changed.to_parquet(folder / name, index=False)
        cases.append((str(folder / name), [name, *words]))

    bad("shorter.parquet", table.iloc[:-5], "frames", "same number of frames")
    bad("missing.parquet", table.drop(columns=["chest.rx", "head.ry"]), "chest.rx", "head.ry")
    bad("unknown.parquet", table.assign(banana=1.0), "banana", "not controls")
    with_nan = table.copy()
    with_nan.loc[10, "chest.rx"] = np.nan
    bad("with_nan.parquet", with_nan, "'chest.rx'", "frame 10", "not a finite number")
    bad("gap.parquet", table.drop(index=20), "not consecutive", "frame 19")
    unused = next(c for c in mode.rig.control_names if c not in set(mode.used))
    bad("unused.parquet", table.assign(**{unused: 123.0}), unused, "off their defaults")
    bad("words.parquet", table.assign(**{"chest.ry": "x"}), "'chest.ry'", "not numbers")
    bad("shifted.parquet", table.assign(frame=table["frame"] + 1), "frame columns")
    return cases


def test_bad_parquets_are_one_line_errors_and_write_nothing(learned_biped, tmp_path, capsys):
    mode, _, examples = learned_biped
    source = examples[1][0]  # the used controls only
    out = tmp_path / "model"
    for edited, words in _bad_files(mode, tmp_path, source):
        fails_in_one_line(learn_argv([(source, edited)], out, "--rig", "biped"), capsys, *words)
        assert not out.exists()
    good = examples[1][1]
    bvh = MOCAP / "cmu_07_05.bvh"
    cases = [
        (learn_argv([(source, good)], out), ["--rig"]),  # parquets without --rig
        (learn_argv([(bvh, bvh)], out, "--rig", "biped"), ["cmu_07_05.bvh", "not a .parquet"]),
        (learn_argv([(source, good)], out, "--rig", "face"), ["face", "root.tx"]),
        (learn_argv([(source, good)], out, "--rig", "nonsense"), ["--rig nonsense", "unknown"]),
        (learn_argv([(source, good)], out, "--rig", "biped", "--frames", "50:200"), ["50:200"]),
        (learn_argv([(source, good)], out, "--rig", "biped", "--fps", "0"), ["--fps"]),
        (learn_argv([(bvh, bvh)], out, "--fps", "30"), ["--fps goes with --rig"]),
    ]
    for argv, words in cases:
        fails_in_one_line(argv, capsys, *words)
        assert not out.exists()


def test_apply_refuses_the_other_mode_and_checks_every_clip_first(learned_biped, tmp_path, capsys):
    _, model, examples = learned_biped
    clips = tmp_path / "clips"
    clips.mkdir()
    shutil.copy(examples[0][0], clips / "a_good.parquet")
    table = pd.read_parquet(examples[1][0]).drop(columns=["hips.rx"])
    table.to_parquet(clips / "b_missing.parquet", index=False)
    out = tmp_path / "out"
    apply = ["edits", "apply", "--model", str(model), "--out", str(out), "--input"]
    fails_in_one_line([*apply, str(clips)], capsys, "b_missing.parquet", "hips.rx")
    fails_in_one_line(
        [*apply, str(MOCAP / "cmu_07_05.bvh")], capsys, "cmu_07_05.bvh", "not a .parquet"
    )
    assert not out.exists()
    # a skeleton-mode model (learned on a BVH pair) refuses parquets, to apply or as a fix
    bvh_model = tmp_path / "bvh_model"
    bvh = str(MOCAP / "cmu_07_05.bvh")
    argv = ["edits", "learn", "--source", bvh, "--edited", bvh, "--frames", "40:70"]
    assert main([*argv, "--out", str(bvh_model)]) == 0
    capsys.readouterr()
    assert json.loads((bvh_model / "learned.json").read_text())["mode"] == "skeleton"
    parquet = str(examples[0][0])
    apply = ["edits", "apply", "--model", str(bvh_model), "--out", str(out), "--input"]
    fails_in_one_line([*apply, parquet], capsys, "controls parquet", "skeleton-mode")
    fix = ["edits", "fix", "--model", str(bvh_model), "--source", bvh, "--fixed", parquet]
    fails_in_one_line([*fix, "--frames", "40:60"], capsys, "controls parquet", "skeleton-mode")
    assert not out.exists()


def test_a_rig_fix_is_learned_and_the_next_frames_suggested(learned_biped, tmp_path, capsys):
    mode, learned_model, _ = learned_biped
    model = tmp_path / "model"
    shutil.copytree(learned_model, model)
    track = library_controls(mode, "Walk Start Stop", 1)
    clip = write_clip(mode, track, tmp_path / "walk_start_stop.parquet")
    truth = rig_controls(LEAN_BACK.apply(track), mode.channels)
    start, stop = 30, 50
    fixed = write_controls(
        tmp_path / "fixed.parquet", controls_table(truth[start:stop], mode.used, start)
    )

    def error_on_fixed_frames(out: Path) -> float:
        argv = ["edits", "apply", "--model", str(model), "--input", str(clip), "--out", str(out)]
        assert main(argv) == 0
        got = read_parquet_controls(out / clip.name, mode)[1]
        return joint_error(mode, got, truth, slice(start, stop))

    before = error_on_fixed_frames(tmp_path / "before")
    capsys.readouterr()
    fix = ["edits", "fix", "--model", str(model), "--source", str(clip), "--fixed"]
    assert main([*fix, str(fixed), "--frames", f"{start}:{stop}", "--suggest", "2"]) == 0
    printed = capsys.readouterr().out
    suggested = [line for line in printed.splitlines() if line.startswith("fix next: frames")]
    assert len(suggested) == 2, printed
    for line in suggested:
        first, last = (int(v) for v in line.split()[3].split(":"))
        assert 0 <= first < last <= track.n_frames and (last <= start or first >= stop), line
    assert (model / "fixes" / "fix_0.parquet").is_file()
    (entry,) = json.loads((model / "learned.json").read_text())["fixes"]
    assert entry["frames"] == [start, stop] and entry["file"] == "fixes/fix_0.parquet"
    after = error_on_fixed_frames(tmp_path / "after")
    with capsys.disabled():
        print(f"\nrig fix: error on the fixed frames cm² before {before:.3g}, after {after:.3g}")
    assert after < 0.5 * before
    # a fix numbered other than --frames, or a BVH: one line, the model folder unchanged
    stored = {p.name: p.read_bytes() for p in model.iterdir() if p.is_file()}
    fails_in_one_line(
        [*fix, str(fixed), "--frames", "10:30"], capsys, "fixed.parquet", "30:50", "10:30"
    )
    bvh = str(MOCAP / "cmu_07_05.bvh")
    fails_in_one_line(
        [*fix, bvh, "--frames", f"{start}:{stop}"], capsys, "cmu_07_05.bvh", "rig-mode edit"
    )
    assert {p.name: p.read_bytes() for p in model.iterdir() if p.is_file()} == stored
    assert [p.name for p in (model / "fixes").iterdir()] == ["fix_0.parquet"]


def test_a_model_learned_with_other_root_controls_is_refused(learned_biped, tmp_path, capsys):
    """learned.json records the rig's root controls, signs and heading joints; a model whose
    record differs from rig mode's table is refused in one line, and one written before the
    signs were recorded is read as the Y-up rigs' 1, 1, 1."""
    _, learned_model, examples = learned_biped
    model = tmp_path / "model"
    shutil.copytree(learned_model, model)
    learned = json.loads((model / "learned.json").read_text())
    assert learned["root_signs"] == [1.0, 1.0, 1.0]
    out = tmp_path / "out"
    argv = ["edits", "apply", "--model", str(model), "--input", str(examples[1][0])]
    write_json_atomic(model / "learned.json", {**learned, "root_signs": [1.0, -1.0, 1.0]})
    fails_in_one_line([*argv, "--out", str(out)], capsys, "root_signs", "[1.0, -1.0, 1.0]", "learn")
    assert not out.exists()
    older = {k: v for k, v in learned.items() if k != "root_signs"}
    write_json_atomic(model / "learned.json", older)
    assert main([*argv, "--out", str(out)]) == 0


def _mapped_walk(biped, folder: Path) -> Path:
    """12 frames of CMU 131_02 mapped onto the biped by the map path (GPR, no refinement),
    written as ``rigmap map`` writes a clip (rigmap.map.outputs)."""
    import dataclasses

    from rigmap.animation.library import build_corpus
    from rigmap.map import JointMap, tracks_from_bvh
    from rigmap.map.clip import MapSettings, map_clip
    from rigmap.map.outputs import write_map_outputs
    from rigmap.map.partial import JointSubset, SubsetMapping
    from rigmap.regression import GaussianProcessRegressor
    from rigmap.regression.features import inverse_features
    from rigmap.regression.kernels import MultiquadricKernel

    Y = build_corpus(biped, "train", seed=0).values()
    pose = biped.pose(biped.expand_used(Y))
    X = inverse_features(
        pose.positions, pose.cog, pose.cog_rotation, n_joints=biped.n_joints, where="corpus"
    )
    retarget = JointMap.from_yaml(ROOT / "conf/retarget/cmu_biped.yaml")
    subset = JointSubset("cmu", "biped", tuple(retarget.joints), "pelvis", "thigh_l", "thigh_r")
    regressor = GaussianProcessRegressor(
        MultiquadricKernel(), n_points=150, n_length_scales=3, cv_splits=2, progress=False
    )
    mapping = SubsetMapping.fit(biped, subset, X, Y, regressor)
    targets = retarget.apply(biped, tracks_from_bvh(MOCAP / "cmu_131_02_walk.bvh"))
    short = dataclasses.replace(targets, positions=targets.positions[240:264:2], fps=60.0)
    settings = MapSettings(refine_iterations=0)
    spread, median = Y.std(axis=0), np.median(Y, axis=0)
    result = map_clip(biped, short, mapping, settings, control_std=spread, hold_values=median)
    return write_map_outputs(folder, result, biped).folder


def test_a_rigmap_map_output_folder_is_an_input(learned_biped, biped, tmp_path):
    """``rigmap map`` writes a folder per clip (controls, per-frame errors, targets, keys,
    summary): ``--input`` takes such a folder, or a folder of them, by its
    ``controls.parquet``, named after the folder; the result is the controls' own."""
    _, model, _ = learned_biped
    mapped = tmp_path / "mapped"
    walk = _mapped_walk(biped, mapped / "cmu_131_02_walk")
    shutil.copytree(walk, mapped / "second_take")
    plain = tmp_path / "plain"
    plain.mkdir()
    shutil.copy(walk / "controls.parquet", plain / "cmu_131_02_walk.parquet")
    outs = {}
    for name, given in (("one", walk), ("several", mapped), ("plain", plain)):
        outs[name] = tmp_path / f"out_{name}"
        argv = ["edits", "apply", "--model", str(model), "--input", str(given)]
        assert main([*argv, "--out", str(outs[name])]) == 0
    applied = json.loads((outs["several"] / "applied.json").read_text())
    assert [Path(row["parquet"]).name for row in applied["clips"]] == [
        "cmu_131_02_walk.parquet",
        "second_take.parquet",
    ]
    assert {Path(row["input"]).name for row in applied["clips"]} == {"controls.parquet"}
    want = pd.read_parquet(outs["plain"] / "cmu_131_02_walk.parquet")
    for name in ("one", "several"):
        got = pd.read_parquet(outs[name] / "cmu_131_02_walk.parquet")
        pd.testing.assert_frame_equal(got, want)
    assert not list(outs["one"].glob("frames*")) and not list(outs["one"].glob("targets*"))
    source = pd.read_parquet(walk / "controls.parquet")
    assert not np.allclose(want[list(biped.used_controls)], source[list(biped.used_controls)])
