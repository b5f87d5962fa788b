"""Bad options and inputs (issue #36 items 2-3): each refused where it is read, in one line
naming the option or file and what it accepts, before anything is written.

Every case runs the real entry point (``rigmap.cli.main`` in this process, or a stage's
``run``) on tiny inputs in a fresh folder, asserts the key part of the message, and asserts
that no file appeared in that folder (the output folder included).
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.cli import main

REPO = Path(__file__).resolve().parents[1]
CONF = str(REPO / "conf")
WALK = REPO.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"


def _files(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*")}


def _refused(argv: list[str], folder: Path, capsys) -> str:
    """Run the CLI; it must exit 2 with one ``rigmap: error:`` line and write nothing."""
    before = _files(folder)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigmap: error: ") and "\n" not in err, err
    assert _files(folder) == before, sorted(_files(folder) - before)
    return err


@pytest.fixture
def here(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _paths(folder: Path) -> list[str]:
    return [f"paths.{k}={folder / k}" for k in ("data", "models", "metrics", "reports")]


# --------------------------------------------------------------------------- rigmap map
MAP_OPTIONS = [
    pytest.param("map.frames=-5", "map.frames=-5: expected an integer >= 1", id="map_frames_-5"),
    pytest.param(
        "map.first_frame=-100",
        "map.first_frame=-100: expected an integer >= 0",
        id="map_first_frame_-100",
    ),
    pytest.param("map.fps=0", "map.fps=0: expected a number > 0", id="map_fps_0"),
    pytest.param("map.fps=-30", "map.fps=-30: expected a number > 0", id="map_fps_-30"),
    pytest.param(
        "map.frames=abc", "map.frames='abc': expected an integer >= 1", id="map_frames_abc"
    ),
    pytest.param("map.frames=2.5", "map.frames=2.5: expected an integer >= 1", id="map_frames_2.5"),
    pytest.param(
        "map.source_fps=0", "map.source_fps=0: expected a number > 0", id="map_source_fps_0"
    ),
    pytest.param(
        "map.first_frame=100000",
        "no frames left to map (the clip has 994 frames; map.first_frame=100000",
        id="map_first_frame_past_the_end",
    ),
]


@pytest.mark.parametrize(("option", "message"), MAP_OPTIONS)
def test_map_option_refused(here, capsys, option, message):
    out = here / "out"
    argv = ["map", f"input={WALK}", "rig=biped", f"out={out}", option, *_paths(here)]
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert message in err
    assert not out.exists()


def test_map_non_ascii_path_unquoted_is_told_to_quote_it(here, capsys):
    """The non-ASCII path trial: Hydra's lexer refuses ``input=/…/wälk.bvh``; the error names
    the override and shows it quoted, and the quoted form gets past the grammar."""
    (here / "ä").mkdir()
    clip = here / "ä" / "wälk.bvh"
    clip.write_bytes(WALK.read_bytes())
    out = here / "out"
    argv = ["map", f"input={clip}", "rig=biped", f"out={out}", *_paths(here), "--config-dir", CONF]
    err = _refused(argv, here, capsys)
    assert f"override 'input={clip}' is not valid Hydra override syntax" in err
    assert f"must be quoted, e.g. input='{clip}'" in err
    argv[1] = f"input='{clip}'"
    err = _refused(argv, here, capsys)
    assert "override syntax" not in err and "train corpus of rig 'biped' does not exist" in err


def _write_npz(path: Path, frames: int = 5, **extra) -> Path:
    arrays = {"positions": np.zeros((frames, 2, 3)), "joint_names": np.array(["a", "b"])}
    np.savez(path, **{**arrays, **extra})
    return path


TRACK_FILES = [
    pytest.param(
        lambda d: (d / "t.csv").write_text("frame,a.x,a.y,a.z\n0,1,2,3\n1,1,2,3\n") and d / "t.csv",
        [],
        "t.csv: the file does not say its frame rate; pass map.source_fps=",
        id="csv_without_fps",
    ),
    pytest.param(
        lambda d: (d / "p.npz").write_bytes(b"\x80\x04pickled bytes") and d / "p.npz",
        [],
        "p.npz: not a readable npz archive (not a zip file",
        id="npz_not_a_zip",
    ),
    pytest.param(
        lambda d: _write_npz(d / "f.npz", fps=np.array([30.0, 60.0])),
        [],
        "f.npz: 'fps' is float64 of shape (2,), expected one number",
        id="npz_fps_array",
    ),
    pytest.param(
        lambda d: _write_npz(d / "s.npz", fps=np.array("30")),
        [],
        "s.npz: 'fps' is <U2 of shape (), expected one number",
        id="npz_fps_string",
    ),
    pytest.param(
        lambda d: _write_npz(d / "w.npz", fps=np.float64(30)),
        ["map.first_frame=10"],
        "w.npz: no frames left to map (the clip has 5 frames; map.first_frame=10",
        id="npz_window_past_the_end",
    ),
    pytest.param(
        lambda d: np.savez(d / "m.npz", positions=np.zeros((5, 2, 3))) or d / "m.npz",
        ["map.source_fps=30"],
        "m.npz: npz lacks ['joint_names']",
        id="npz_without_joint_names",
    ),
    pytest.param(
        lambda d: _write_npz(d / "o.npz", fps=30.0, positions=np.zeros((5, 2), dtype=object)),
        [],
        "o.npz: positions are object of shape (5, 2); expected numbers of shape (F, J, 3)",
        id="npz_object_positions",
    ),
]


@pytest.mark.parametrize(("make", "options", "message"), TRACK_FILES)
def test_map_tracks_file_refused(here, capsys, make, options, message):
    source = make(here)
    out = here / "out"
    argv = ["map", f"input={source}", "rig=biped", f"out={out}", *options, *_paths(here)]
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert message in err
    assert not out.exists()


def test_map_npz_beyond_memory_refused(here, capsys, monkeypatch):
    """A clip whose frames would not fit in memory is refused before reading them, naming
    map.frames (the machine is made small here: 1 kB available)."""
    import rigmap.memory

    monkeypatch.setattr(rigmap.memory, "available_bytes", lambda: 1000)
    source = _write_npz(here / "big.npz", frames=1000, fps=np.float64(30))
    out = here / "out"
    argv = ["map", f"input={source}", "rig=biped", f"out={out}", "map.fps=null", *_paths(here)]
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert "map.frames=None: 1000 frames of 2 joints need about" in err
    assert "lower map.frames" in err


def test_map_npz_reads_only_the_frames_mapped(tmp_path):
    """The 10 M-frame npz trial, scaled down: 10 frames of a 500 000-frame file cost about
    10 frames of memory (the whole file as float64 would be 24 MB), and are the right ones."""
    from rigmap.map.tracks import FrameWindow, read_tracks

    frames = 500_000
    positions = np.arange(frames * 2 * 3, dtype=np.float32).reshape(frames, 2, 3)
    np.savez(
        tmp_path / "long.npz",
        positions=positions,
        joint_names=np.array(["a", "b"]),
        fps=np.float64(120),
    )
    tracemalloc.start()
    try:
        tracks = read_tracks(tmp_path / "long.npz", unit="cm", window=FrameWindow(7, 10, 30.0))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000, peak
    np.testing.assert_array_equal(tracks.positions, positions[7 : 7 + 40 : 4])
    assert tracks.fps == 30.0


@pytest.mark.parametrize("save", [np.savez, np.savez_compressed], ids=["stored", "compressed"])
@pytest.mark.parametrize(
    ("first", "count", "fps"), [(0, None, None), (5, None, 7.0), (3, 100, 40.0), (598, 10, None)]
)
def test_map_npz_window_reads_the_same_frames_in_small_blocks(
    tmp_path, monkeypatch, save, first, count, fps
):
    """Cut while reading, block by block, an npz gives the frames slicing the whole would."""
    import rigmap.map.tracks
    from rigmap.map.tracks import FrameWindow, read_tracks

    monkeypatch.setattr(rigmap.map.tracks, "NPZ_BLOCK_BYTES", 1000)
    positions = np.random.default_rng(0).normal(size=(600, 3, 3))
    save(tmp_path / "t.npz", positions=positions, joint_names=np.array(["a", "b", "c"]), fps=120)
    window = FrameWindow(first, count, fps)
    tracks = read_tracks(tmp_path / "t.npz", unit="cm", window=window)
    np.testing.assert_array_equal(tracks.positions, positions[window.slice(120.0)])


def test_map_bvh_5000_deep_hierarchy_parses(here, capsys):
    """A 5 000-deep chain parses (no RecursionError); the map then names what it lacks."""
    from rigmap.animation.bvh import read_bvh

    depth = 5000
    lines = [
        "HIERARCHY",
        "ROOT j0",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
    ]
    for k in range(1, depth):
        lines += [f"JOINT j{k}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}", *["}"] * depth]
    row = " ".join(["0"] * (6 + 3 * (depth - 1)))
    lines += ["MOTION", "Frames: 2", "Frame Time: 0.0333333", row, row]
    deep = here / "deep.bvh"
    deep.write_text("\n".join(lines) + "\n")
    motion = read_bvh(deep)
    assert motion.n_joints == depth and motion.parents[-1] == depth - 2
    out = here / "out"
    argv = ["map", f"input={deep}", "rig=biped", f"out={out}", *_paths(here), "--config-dir", CONF]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rigmap: error: ") and "\n" not in err
    assert "deep.bvh: skeleton not matched to rig 'biped': unmatched pelvis (role hips)" in err
    # the skeleton matcher's draft map is the one file written, by design, as the error says
    assert "draft retarget map written to" in err
    assert _files(here) == {deep, out, out / "deep.retarget.draft.yaml"}


# --------------------------------------------------------------------------- rigmap pose
POSE_TARGETS = [
    pytest.param(
        lambda d: (d / "t.json").write_bytes(bytes(range(128, 256))) and d / "t.json",
        "t.json: not a text effector targets file (not UTF-8",
        id="pose_targets_binary",
    ),
    pytest.param(
        lambda d: (d / "t.json").write_text("{") and d / "t.json",
        "t.json: not valid JSON",
        id="pose_targets_bad_json",
    ),
    pytest.param(
        lambda d: (d / "folder.json").mkdir() or d / "folder.json",
        "effector targets file folder.json is a folder, not a file",
        id="pose_targets_folder",
    ),
]


@pytest.mark.parametrize(("make", "message"), POSE_TARGETS)
def test_pose_targets_refused(here, capsys, make, message):
    targets = make(here).name
    out = here / "out"
    argv = ["pose", "rig=biped", f"targets={targets}", f"out={out}", *_paths(here)]
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert message in err
    assert not out.exists()


# --------------------------------------------------------------------------- rigmap rigs / corpus
RENDER = [
    pytest.param(
        lambda d: (d / "c.json").write_text('{"root.tx": [1]}') and ["--controls", "c.json"],
        "c.json: control 'root.tx' is [1]; expected a number",
        id="render_controls_value_a_list",
    ),
    pytest.param(
        lambda d: (d / "c.json").write_text("[1, 2]") and ["--controls", "c.json"],
        "c.json: expected a JSON object {control: value}",
        id="render_controls_a_list",
    ),
    pytest.param(
        lambda d: (d / "c.json").write_text("{") and ["--controls", "c.json"],
        "c.json: not valid JSON",
        id="render_controls_bad_json",
    ),
    pytest.param(
        lambda d: (d / "c.json").write_bytes(b"\xff\xfe\x00") and ["--controls", "c.json"],
        "c.json: not a text --controls file (not UTF-8",
        id="render_controls_binary",
    ),
    pytest.param(
        lambda d: (d / "cdir").mkdir() or ["--controls", "cdir"],
        "--controls file cdir is a folder, not a file",
        id="render_controls_folder",
    ),
]


@pytest.mark.parametrize(("make", "message"), RENDER)
def test_rigs_render_controls_refused(here, capsys, make, message):
    flags = make(here)
    err = _refused(["rigs", "render", "biped", *flags, "--out", "pose.png"], here, capsys)
    assert message in err
    assert not (here / "pose.png").exists()


def test_rigs_render_out_folder_refused(here, capsys):
    (here / "shots").mkdir()
    err = _refused(["rigs", "render", "biped", "--out", "shots"], here, capsys)
    assert "--out shots is a folder; expected a file to write, e.g. shots/pose.png" in err


def test_rigs_render_random_negative_refused(here, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["rigs", "render", "biped", "--random", "-5", "--out", "pose.png"])
    assert exit_.value.code == 2
    assert "argument --random: expected an integer >= 0 (a random seed), got '-5'" in (
        capsys.readouterr().err
    )
    assert _files(here) == set()


def test_corpus_show_out_folder_refused(here, capsys):
    (here / "sheets").mkdir()
    argv = ["corpus", "show", "rig=biped", "clip=Walk", "--out", "sheets"]
    err = _refused(argv, here, capsys)
    assert "--out sheets is a folder; expected a file to write" in err


def test_export_blend_torch_rig_refused(here, capsys):
    pd.DataFrame({"frame": [0, 1], "root.tx": [0.0, 1.0]}).to_parquet(here / "c.parquet")
    argv = ["export-blend", "--rig", "biped", "--controls", "c.parquet", "--out", "x.blend"]
    err = _refused(argv, here, capsys)
    assert "rig 'biped' is a TorchRig, not a Blender rig" in err
    assert not (here / "x.blend").exists()


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        pytest.param(
            ["--controls", "cdir", "--out", "x.blend"],
            "--controls cdir is a folder; expected a .parquet file",
            id="export_blend_controls_folder",
        ),
        pytest.param(
            ["--controls", "c.parquet", "--out", "cdir"],
            "--out cdir is a folder; expected a file to write, e.g. cdir/mapped.blend",
            id="export_blend_out_folder",
        ),
    ],
)
def test_export_blend_folder_refused(here, capsys, flags, message):
    (here / "cdir").mkdir()
    pd.DataFrame({"frame": [0], "root.tx": [0.0]}).to_parquet(here / "c.parquet")
    err = _refused(["export-blend", "--rig", "rigify_human", *flags], here, capsys)
    assert message in err


# --------------------------------------------------------------------------- rigmap fit
FIT_OVERRIDES = [
    pytest.param(
        "budget.gpr_points=abc",
        "budget.gpr_points='abc': expected an integer >= 1 (a number of GPR points)",
        id="fit_gpr_points_abc",
    ),
    pytest.param("seed=-1", "seed=-1: expected an integer >= 0 (a random seed)", id="fit_seed_-1"),
    pytest.param(
        "budget.samples=2.5",
        "budget.samples=2.5: expected an integer >= 1 (a number of supersamples)",
        id="fit_samples_2.5",
    ),
    pytest.param("budget.epochs=0", "budget.epochs=0: expected an integer >= 1", id="fit_epochs_0"),
]


@pytest.mark.parametrize(("override", "message"), FIT_OVERRIDES)
def test_fit_override_refused(here, capsys, override, message):
    argv = ["fit", "rig=biped", "regressor=gpr", "sampler=none", override, *_paths(here)]
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert message in err


# --------------------------------------------------------------------------- supersample stage
def test_supersample_beyond_memory_refused(here):
    """budget.samples=1e9 is refused before the corpus is read or anything drawn."""
    from omegaconf import OmegaConf

    from rigmap.app.stage import stage_config
    from rigmap.cli import compose_config
    from rigmap.memory import MemoryBudgetError
    from stage_scripts import load_stage

    overrides = ["rig=biped", "sampler=pca_gaussian", "budget.samples=1000000000", *_paths(here)]
    cfg = stage_config(compose_config(overrides, Path(CONF)))
    assert OmegaConf.select(cfg, "budget.samples") == 10**9
    with pytest.raises(
        MemoryBudgetError,
        match=r"^budget\.samples=1000000000: 1000000000 "
        r"samples of rig 'biped' need about [\d.]+ GiB of memory",
    ):
        load_stage("supersample").run(cfg, progress=False)
    assert _files(here) == set()


# --------------------------------------------------------------------------- rigmap edits
EDITS = [
    pytest.param(
        "add",
        "edits.run=biped",
        "edits.run='biped': expected a list of names, e.g. 'edits.run=[biped]'",
        id="edits_run_a_string",
    ),
    pytest.param(
        "fit",
        "edits.run=biped",
        "edits.run='biped': expected a list of names",
        id="edits_fit_run_a_string",
    ),
    pytest.param(
        "add",
        "edits.names=arm_swing",
        "edits.names='arm_swing': expected a list of names",
        id="edits_names_a_string",
    ),
    pytest.param(
        "add",
        "+edits.refine.rounds=-1",
        "edits.refine.rounds must be an integer >= 1, got -1",
        id="edits_add_rounds_-1",
    ),
    pytest.param(
        "add",
        "+edits.refine.random_seeds=0",
        "edits.refine.random_seeds must be an integer >= 1, got 0",
        id="edits_add_random_seeds_0",
    ),
    pytest.param(
        "add",
        "edits.weights.kinematic=nan",
        "edits.weights.kinematic=nan: expected a finite number >= 0",
        id="edits_weight_nan",
    ),
    pytest.param(
        "add",
        "edits.weights.kinematic=null",
        "edits.weights.kinematic=None: expected a finite number >= 0",
        id="edits_weight_null",
    ),
    pytest.param(
        "add",
        "edits.weights.acceleration=[1,2]",
        "edits.weights.acceleration=[1, 2]: expected a finite number >= 0",
        id="edits_weight_a_list",
    ),
    pytest.param(
        "apply",
        "edits.weights.kinematic=-1",
        "edits.weights.kinematic=-1: expected a finite number >= 0",
        id="edits_weight_negative",
    ),
    pytest.param(
        "evaluate",
        "edits.ablation.full=[1,1]",
        "edits.ablation.full=[1, 1]: expected {kinematic, kinematic_regularizer, acceleration, "
        "acceleration_regularizer} or a list of 4 numbers",
        id="edits_ablation_two_weights",
    ),
]


@pytest.mark.parametrize(("verb", "override", "message"), EDITS)
def test_edits_option_refused(here, capsys, verb, override, message):
    argv = ["edits", verb, "edits.names=[arm_swing]", override, *_paths(here)]
    if override.startswith("edits.names"):
        argv.remove("edits.names=[arm_swing]")
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert message in err


# --------------------------------------------------------------------------- rigmap synth run
SCRIPTS = [
    pytest.param(
        "commands:\n  - idle: {frames: 10000000}\n",
        [],
        "the commands ask for 10000000 frames, more than latent.max_script_frames=100000",
        id="synth_idle_10M_frames",
    ),
    pytest.param(
        "commands:\n  - idle: {frames: 30}\n  - transition: {model: roar, idle_frames: 30}\n",
        ["latent.max_script_frames=50"],
        "the commands ask for 60 frames, more than latent.max_script_frames=50",
        id="synth_over_a_lowered_cap",
    ),
    pytest.param(
        "commands:\n  - idle: {frames: abc}\n",
        [],
        "command 1: frames must be a whole number >= 0, got 'abc'",
        id="synth_idle_frames_abc",
    ),
    pytest.param(
        "commands:\n  - idle: {frames: -3}\n",
        [],
        "command 1: frames must be a whole number >= 0, got -3",
        id="synth_idle_frames_-3",
    ),
    pytest.param(
        "commands:\n  - idle: {frames: 4}\n",
        ["latent.max_script_frames=0"],
        "latent.max_script_frames=0: expected an integer >= 1",
        id="synth_cap_0",
    ),
]


@pytest.mark.parametrize(("script", "overrides", "message"), SCRIPTS)
def test_synth_script_refused(here, capsys, script, overrides, message):
    """Refused from the script alone, before the models load (there are none here)."""
    (here / "s.yaml").write_text(script)
    argv = ["synth", "run", "s.yaml", "rig=face", *overrides, *_paths(here), "--out", "o.parquet"]
    err = _refused([*argv, "--config-dir", CONF], here, capsys)
    assert message in err
    assert not (here / "o.parquet").exists()


def test_synth_controller_stops_at_the_cap():
    """A command the script cannot size (playing a take) still stops at the cap."""
    from latent_face import face_models, face_transitions
    from rigmap.latent import LatentInputError
    from rigmap.latent.synthesis import Controller, Play

    fitted = face_models()
    controller = Controller(
        fitted.models, start="happy", takes=fitted.sets, transitions=face_transitions(), seed=0
    )
    take = fitted.sets["happy"].names[0]
    with pytest.raises(
        LatentInputError, match=r"go on past 5 frames \(latent\.max_script_frames\)"
    ):
        controller.run([Play(take)], max_frames=5)


def test_synth_run_shows_progress(capsys):
    """The frames played are counted on a progress bar (stderr), as a long run goes."""
    from latent_face import face_models, face_transitions
    from rigmap.latent.synthesis import Controller, Idle

    fitted = face_models()
    controller = Controller(
        fitted.models, start="happy", takes=fitted.sets, transitions=face_transitions(), seed=0
    )
    frames = controller.run([Idle(frames=6)], max_frames=100, progress=True)
    assert len(frames) >= 6
    assert "synthesis" in capsys.readouterr().err
