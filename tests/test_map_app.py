"""`rigmap map` / `rigmap pose` end to end (rigmap.app.map_job) on the CMU walk, and its bad inputs.

A small biped project is built in a temporary folder (the train corpus and its poses, as
the animate and pose stages write them); the map model is fitted there with a small GPR.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.app.map_job import MapConfigError, map_from_config, map_settings, pose_from_config
from rigmap.cli import compose_config, find_config_dir, main
from rigmap.map.subset_model import RECORD_FILE, SubsetModelError
from rigmap.map.tracks import TracksError, tracks_from_bvh

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "mocap"
WALK = MOCAP / "cmu_131_01_walk.bvh"
CONF = find_config_dir(Path(__file__).resolve().parents[1] / "conf")
SMALL_MODEL = ["budget.gpr_points=80", "budget.length_scales=3", "budget.cv_splits=2"]
OUTPUTS = ["controls.parquet", "frames.parquet", "keys.json", "preview.gif", "preview.png",
           "result.bvh", "summary.json", "targets.parquet"]  # fmt: skip


def map_config(project: Path, *overrides: str) -> dict:
    from omegaconf import OmegaConf

    from rigmap.app.stage import stage_config

    paths = [f"paths.data={project / 'data'}", f"paths.models={project / 'models'}"]
    cfg = compose_config(["rig=biped", *paths, *SMALL_MODEL, *overrides], CONF,
                         config_name="map")  # fmt: skip
    return OmegaConf.to_container(stage_config(cfg), resolve=True)


@pytest.fixture(scope="module")
def project(tmp_path_factory, biped):
    """data/biped/corpus and poses of a temporary project (seed 0, as the stages write them)."""
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("project")
    layout = Layout(data=root / "data", models=root / "models")
    write_corpora(biped, layout, seed=0, fps=24, variation=1.0)
    pose_corpora(biped, layout, batch_size=512, progress=False)
    return root


@pytest.fixture(scope="module")
def mapped(project):
    """Eight frames of the walk at 30 fps, mapped with one refinement iteration."""
    log: list[str] = []
    out = project / "out"
    config = map_config(project, f"input={WALK}", f"out={out}", "map.first_frame=240",
                        "map.frames=8", "map.settings.refine_iterations=1")  # fmt: skip
    (clip,) = map_from_config(config, config_dir=CONF, log=log.append)
    return clip, log, config


def test_map_writes_every_output_with_a_sensible_error(mapped, biped):
    clip, log, _ = mapped
    assert sorted(p.name for p in clip.folder.iterdir()) == OUTPUTS
    assert any("fitting on" in line for line in log)  # the first map fits the model
    controls = pd.read_parquet(clip.folder / "controls.parquet")
    assert controls.shape == (8, 1 + biped.n_controls)
    frames = pd.read_parquet(clip.folder / "frames.parquet")
    assert ((frames["confidence"] > 0) & (frames["confidence"] <= 1)).all()
    summary = clip.summary
    assert summary["frames"] == 8 and summary["fps"] == pytest.approx(30.0, rel=1e-4)
    assert len(summary["mapped_joints"]) == 24
    # the retargeted walk is reachable: within a few cm on the 24 mapped joints of a 178 cm rig
    assert 0.1 < summary["joint_error_rms_cm"] < 20.0
    assert summary["joint_error_rms_percent_of_height"] == pytest.approx(
        100 * summary["joint_error_rms_cm"] / summary["rig_height_cm"]
    )
    np.testing.assert_allclose(frames["joint_error_cm"].pow(2).mean() ** 0.5,
                               summary["joint_error_rms_cm"])  # fmt: skip


def test_the_cached_model_is_reused_and_refitted_for_another_subset(mapped, project):
    clip, _, config = mapped
    log: list[str] = []
    (again,) = map_from_config(config, config_dir=CONF, log=log.append)
    assert not any("fitting on" in line for line in log)
    assert again.summary["joint_error_rms_cm"] == pytest.approx(clip.summary["joint_error_rms_cm"])
    record = json.loads((project / "models/biped/map-cmu_biped" / RECORD_FILE).read_text())
    assert record["rig"] == "biped" and len(record["subset"]["joints"]) == 24


def test_a_model_for_another_rig_or_subset_is_refused(mapped, project, tmp_path):
    import shutil

    _, _, config = mapped
    cached = project / "models/biped/map-cmu_biped"
    for key, value, expected in (("rig", "quadruped", "fitted for rig 'quadruped'"),
                                 ("rig_fingerprint", "0" * 64, "another version of rig"),
                                 ("subset", {"name": "feet", "joints": ["foot_l"]},
                                  "joint subset 'feet'")):  # fmt: skip
        other = tmp_path / f"other_{key}"
        shutil.copytree(cached, other)
        record = json.loads((other / RECORD_FILE).read_text())
        record[key] = value
        (other / RECORD_FILE).write_text(json.dumps(record))
        out = tmp_path / f"out_{key}"
        with pytest.raises(SubsetModelError, match=expected) as error:
            map_from_config({**config, "model": str(other), "out": str(out)}, config_dir=CONF)
        assert str(other) in str(error.value)
        assert not out.exists()


def test_pose_from_seven_effectors(project, biped, tmp_path):
    pose = biped.pose(biped.controls.defaults[None])
    world = (np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :])[0]
    joints = ["pelvis", "spine_chest", "head", "hand_l", "hand_r", "foot_l", "foot_r"]
    targets = {j: world[biped.joint_names.index(j)].tolist() for j in joints}
    targets["hand_l"][1] += 25.0  # raise the left hand
    path = tmp_path / "effectors.json"
    path.write_text(json.dumps({"rig": "biped", "targets": targets}))
    distances = {}
    for mode in ("drag", "batch"):
        config = map_config(project, f"targets={path}", f"map.pose_mode={mode}",
                            f"out={tmp_path / mode}")  # fmt: skip
        out = pose_from_config(config, log=lambda _: None)
        written = json.loads((out / "controls.json").read_text())
        assert sorted(p.name for p in out.iterdir()) == ["controls.json", "pose_0.png"]
        assert written["effectors"] == joints
        distances[mode] = written["poses"][0]["target_distance_rms_cm"]
    assert distances["drag"] < 5.0 and distances["batch"] < 5.0
    with pytest.raises(MapConfigError, match=r"map.pose_mode: expected 'drag' or 'batch'"):
        pose_from_config(map_config(project, f"targets={path}", "map.pose_mode=sideways",
                                    f"out={tmp_path / 'no'}"), log=lambda _: None)  # fmt: skip
    with pytest.raises(MapConfigError, match=r"map.drag: .*steps must be an integer >= 1"):
        pose_from_config(map_config(project, f"targets={path}", "map.drag.steps=0",
                                    f"out={tmp_path / 'no'}"), log=lambda _: None)  # fmt: skip
    assert not (tmp_path / "no").exists()


# --------------------------------------------------------------------------- bad input
def _bvh_variant(tmp_path: Path, name: str, edit) -> Path:
    lines = WALK.read_text().splitlines()
    path = tmp_path / f"{name}.bvh"
    path.write_text("\n".join(edit(lines, lines.index("MOTION"))) + "\n")
    return path


def _replace_value(line: str, column: int, value: str) -> str:
    values = line.split()
    values[column] = value
    return " ".join(values)


BAD_BVH = {
    "truncated": (lambda lines, m: lines[: m + 10], r"truncated: file ends after 7 of the 994"),
    "channels": (lambda lines, m: [*lines[: m + 3], " ".join(lines[m + 3].split()[:-2]),
                                   *lines[m + 4 :]], r"frame 0 has 94 values, expected 96"),
    "nan": (lambda lines, m: [*lines[: m + 3], _replace_value(lines[m + 3], 5, "nan"),
                              *lines[m + 4 :]], r"value 'nan' is not a finite number"),
    "inf": (lambda lines, m: [*lines[: m + 3], _replace_value(lines[m + 3], 7, "-inf"),
                              *lines[m + 4 :]], r"value '-inf' is not a finite number"),
    "empty": (lambda lines, m: [*lines[:m], "MOTION", "Frames: 0", "Frame Time: .0083333"],
              r"has no frames"),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD_BVH))
def test_a_bad_bvh_is_one_clear_error_and_nothing_is_written(case, tmp_path):
    edit, message = BAD_BVH[case]
    path = _bvh_variant(tmp_path, case, edit)
    out = tmp_path / "out"
    config = map_config(tmp_path / "empty_project", f"input={path}", f"out={out}")
    with pytest.raises(Exception, match=message) as error:
        map_from_config(config, config_dir=CONF)
    assert str(path) in str(error.value)
    assert not out.exists() and not (tmp_path / "empty_project").exists()


def test_a_bvh_without_the_joints_of_a_given_map_is_one_clear_error(tmp_path):
    """With map.retarget given there is no skeleton matching (rigmap.map.skeleton_match)."""
    path = _bvh_variant(
        tmp_path,
        "unmapped",
        lambda lines, m: [x.replace("JOINT LeftKnee", "JOINT LKnee") for x in lines],
    )
    out = tmp_path / "out"
    config = map_config(tmp_path / "p", f"input={path}", f"out={out}", "map.retarget=cmu_biped")
    with pytest.raises(Exception, match=r"'LeftKnee' \(drives 'shin_l'\)") as error:
        map_from_config(config, config_dir=CONF)
    assert str(path) in str(error.value)
    assert not out.exists() and not (tmp_path / "p").exists()


def test_the_other_cmu_conversion_is_matched_and_mapped_with_the_cached_model(mapped, project):
    """cmu_07_12 (other joint names, a T-pose at frame 0, an all-zero frame): its skeleton
    is matched, the map saved and named in the log, the model of the default map reused."""
    log: list[str] = []
    out = project / "out_hahne"
    config = map_config(
        project,
        f"input={MOCAP / 'cmu_07_12.bvh'}",
        f"out={out}",
        "map.first_frame=60",
        "map.frames=4",
        "map.settings.refine_iterations=1",
    )
    (clip,) = map_from_config(config, config_dir=CONF, log=log.append)
    saved = out / "cmu_07_12.retarget.yaml"
    assert saved.is_file() and any(f"retarget map used: {saved}" in line for line in log)
    assert any("frame 0 is a T-pose (excluded), glitch frames" in line for line in log), log
    assert not any("fitting on" in line for line in log)
    assert clip.summary["frames"] == 4 and 0.1 < clip.summary["joint_error_rms_cm"] < 20.0


def test_a_bad_bvh_in_a_batch_stops_it_before_any_clip_is_mapped(tmp_path):
    folder = tmp_path / "batch"
    folder.mkdir()
    (folder / "a_good.bvh").write_text(WALK.read_text())
    bad = _bvh_variant(folder, "b_truncated", BAD_BVH["truncated"][0])
    out = tmp_path / "out"
    config = map_config(tmp_path / "p", f"input={folder}", f"out={out}")
    with pytest.raises(Exception, match="truncated") as error:
        map_from_config(config, config_dir=CONF)
    assert str(bad) in str(error.value) and not out.exists()


def _walk_table(unit_scale: float = 1.0) -> pd.DataFrame:
    tracks = tracks_from_bvh(WALK)
    columns = {"frame": np.arange(40)}
    for j, name in enumerate(tracks.joint_names):
        for a, axis in enumerate("xyz"):
            columns[f"{name}.{axis}"] = tracks.positions[240:280, j, a] * unit_scale
    return pd.DataFrame(columns)


@pytest.mark.parametrize(
    ("case", "edit", "error", "message"),
    [
        ("missing_column", lambda t: t.drop(columns=["LeftKnee.z"]), TracksError,
         r"joints missing coordinate columns: \{'LeftKnee': \['z'\]\}"),
        ("missing_joint", lambda t: t.drop(columns=["Head.x", "Head.y", "Head.z"]), Exception,
         r"'Head' \(drives 'head'\)"),
        ("nan", lambda t: t.assign(**{"Hips.y": t["Hips.y"].where(t.index != 3)}), TracksError,
         r"joint 'Hips' y is nan at frame 3"),
        ("empty", lambda t: t.iloc[:0], TracksError, r"the clip is empty"),
    ],
)  # fmt: skip
def test_bad_joint_tracks_are_one_clear_error(case, edit, error, message, tmp_path):
    path = tmp_path / f"{case}.parquet"
    edit(_walk_table()).to_parquet(path)
    out = tmp_path / "out"
    config = map_config(tmp_path / "p", f"input={path}", f"out={out}", "map.source_fps=120")
    with pytest.raises(error, match=message) as raised:
        map_from_config(config, config_dir=CONF)
    assert str(path) in str(raised.value) and not out.exists()


def test_joint_tracks_map_like_the_bvh_they_came_from(mapped, tmp_path):
    """The walk's joint positions in metres (a CSV) map as the BVH itself does."""
    clip, _, config = mapped
    path = tmp_path / "walk.csv"
    table = tracks_from_bvh(WALK)
    columns = {"frame": np.arange(table.n_frames)}
    for j, name in enumerate(table.joint_names):
        for a, axis in enumerate("xyz"):
            columns[f"{name}.{axis}"] = table.positions[:, j, a] / 100.0
    pd.DataFrame(columns).to_csv(path, index=False)
    settings = {**config["map"], "unit": "m", "source_fps": 120.0}
    (tracks,) = map_from_config({**config, "map": settings, "input": str(path),
                                 "out": str(tmp_path / "out")}, config_dir=CONF)  # fmt: skip
    assert tracks.summary["joint_error_rms_cm"] == pytest.approx(
        clip.summary["joint_error_rms_cm"], rel=1e-6
    )


def test_an_unknown_subset_and_a_missing_input_are_named(tmp_path):
    with pytest.raises(MapConfigError, match="no input"):
        map_from_config(map_config(tmp_path), config_dir=CONF)
    with pytest.raises(MapConfigError, match=r"no joint subset 'hands'.*has \['effectors'.*"
                                             r"map/default\.yaml.*--config-dir"):  # fmt: skip
        map_from_config(map_config(tmp_path, f"input={WALK}", "map.subset=hands"),
                        config_dir=CONF)  # fmt: skip
    with pytest.raises(FileNotFoundError, match=r"nope\.bvh does not exist"):
        map_from_config(map_config(tmp_path, "input=nope.bvh"), config_dir=CONF)


def test_the_cli_prints_a_bad_input_as_one_message(tmp_path, capsys):
    path = _bvh_variant(tmp_path, "channels", BAD_BVH["channels"][0])
    code = main(["map", f"input={path}", "rig=biped", f"out={tmp_path / 'out'}",
                 f"paths.models={tmp_path / 'models'}"])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("rigmap: error: ") and str(path) in err and "Traceback" not in err


def test_the_map_mocap_stage_scores_both_cmu_walks(project, tmp_path):
    from rigmap.app.map_stage import map_mocap

    config = map_config(project, f"paths.metrics={tmp_path / 'metrics'}",
                        "map.mocap_stage.frames=3", "map.settings.refine_iterations=0",
                        "map.preview=false")  # fmt: skip
    written = map_mocap(config, config_dir=CONF, log=lambda _: None)
    assert [p.name for p in written] == ["cmu_131_01_walk.json", "cmu_131_02_walk.json"]
    for path in written:
        metrics = json.loads(path.read_text())
        summary = json.loads((Path(metrics["outputs"]) / "summary.json").read_text())
        assert metrics["frames"] == 3 and metrics["rig"] == "biped"
        assert metrics["joint_error_rms_cm"] == summary["joint_error_rms_cm"] > 0
        assert metrics["keys"] <= metrics["frames_times_keyed_controls"]
        per_frame = pd.read_csv(path.with_suffix(".csv"))
        assert list(per_frame.columns) == ["frame", "joint_error_cm", "confidence"]
        assert len(per_frame) == 3
    model = project / "data/biped/map/model"  # the stage's own model, not models/biped/
    assert json.loads((model / RECORD_FILE).read_text())["subset"]["name"] == "cmu_biped"


def test_the_stage_without_a_corpus_exits_with_one_message(tmp_path):
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[1] / "pipelines" / "map_mocap.py"
    done = subprocess.run(
        [sys.executable, str(script), "rig=biped", f"paths.data={tmp_path / 'data'}",
         f"paths.metrics={tmp_path / 'metrics'}", f"paths.models={tmp_path / 'models'}"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error: map_mocap: ") and "Traceback" not in done.stderr
    assert "corpus/train.parquet" in done.stderr
    assert (
        not (tmp_path / "metrics").exists() and not (tmp_path / "data" / "biped" / "map").exists()
    )


def test_face_ik_from_the_six_landmarks(tmp_path):
    """Fig. 10: the face posed from its landmarks, the mouth corners raised 0.8 cm."""
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.rigs import load
    from rigmap.store import Layout

    face = load("face")
    layout = Layout(data=tmp_path / "data", models=tmp_path / "models")
    write_corpora(face, layout, seed=0, fps=30, variation=1.0)
    pose_corpora(face, layout, batch_size=512, progress=False)
    rest = face.pose(face.controls.defaults[None])
    world = (np.asarray(rest.positions) + np.asarray(rest.cog)[:, None, :])[0]
    targets = {name: world[k].tolist() for k, name in enumerate(face.joint_names)}
    for corner in ("mouth_corner_l", "mouth_corner_r"):
        targets[corner][1] += 0.8
    path = tmp_path / "smile.json"
    path.write_text(json.dumps({"rig": "face", "targets": targets}))
    config = map_config(tmp_path, "rig=face", f"targets={path}", f"out={tmp_path / 'pose'}")
    out = pose_from_config(config, log=lambda _: None)
    written = json.loads((out / "controls.json").read_text())
    assert written["effectors"] == list(face.joint_names)
    assert written["poses"][0]["target_distance_rms_cm"] < 0.5  # of a 0.8 cm smile
    assert (out / "pose_0.png").stat().st_size > 0


def test_the_hydra_app_names_a_missing_input(tmp_path):
    import subprocess
    import sys

    script = Path(__file__).resolve().parents[1] / "pipelines" / "map.py"
    done = subprocess.run([sys.executable, str(script), "rig=biped", "input=nope.bvh",
                           f"out={tmp_path / 'out'}"], capture_output=True, text=True,
                          timeout=600)  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("error: map: input nope.bvh does not exist")


def test_a_rigs_own_settings_go_over_the_map_settings():
    from omegaconf import OmegaConf

    cfg = compose_config(["map.settings.key_tolerance_cm=0.7"], CONF, config_name="map")
    options = OmegaConf.to_container(cfg.map, resolve=True)
    biped_settings, human = map_settings(options, "biped"), map_settings(options, "rigify_human")
    assert biped_settings.hold == ("*.ik_fk", "*.follow")
    assert human.hold == ("*.IK_FK", "*.IK_Stretch", "*_follow", "root.rz")  # Rigify's names
    assert human.key_tolerance_cm == biped_settings.key_tolerance_cm == 0.7
    assert human.feet == ("DEF-foot.L", "DEF-foot.R")
    options["rigs"]["rigify_human"]["settings"]["no_such_setting"] = 1
    with pytest.raises(MapConfigError, match=r"map\.rigs\.rigify_human\.settings"):
        map_settings(options, "rigify_human")


# ------------------------------------------------------------------ frame cap and progress
def test_map_frames_over_the_cap_is_refused_before_anything_is_read(tmp_path):
    out = tmp_path / "out"
    config = map_config(
        tmp_path, "input=nope.bvh", f"out={out}", "map.frames=200", "map.max_frames=100"
    )
    with pytest.raises(MapConfigError) as caught:  # the missing file is never reached
        map_from_config(config, config_dir=CONF)
    assert str(caught.value) == (
        "map.frames=200: expected an integer in 1..100 (map.max_frames) or null (all)"
    )
    assert not out.exists()


@pytest.mark.parametrize("cap", ["0", "null", "2.5", "abc"])
def test_a_bad_frame_cap_is_named(tmp_path, cap):
    config = map_config(tmp_path, f"input={WALK}", f"map.max_frames={cap}")
    with pytest.raises(MapConfigError, match=r"^map\.max_frames=.*: expected an integer >= 1"):
        map_from_config(config, config_dir=CONF)


def test_a_bvh_longer_than_the_cap_is_refused_before_it_is_mapped(tmp_path):
    out = tmp_path / "out"
    config = map_config(tmp_path, f"input={WALK}", f"out={out}", "map.max_frames=10")
    with pytest.raises(TracksError) as caught:
        map_from_config(config, config_dir=CONF)
    frames = len(range(tracks_from_bvh(WALK).positions.shape[0])[::4])  # 120 fps at 30: every 4th
    assert str(caught.value) == (
        f"{WALK}: {frames} frames to map, more than map.max_frames=10; set map.frames to "
        "1..10 (or raise map.max_frames)"
    )
    assert not out.exists()


def test_an_npz_longer_than_the_cap_is_refused_before_its_frames_are_read(tmp_path, monkeypatch):
    import rigmap.map.tracks

    def no_allocation(*args):
        raise AssertionError("the frames were sized for reading")

    monkeypatch.setattr(rigmap.map.tracks, "check_memory", no_allocation)
    path = tmp_path / "long.npz"
    np.savez(path, positions=np.zeros((50, 2, 3)), joint_names=np.array(["a", "b"]), fps=30.0)
    config = map_config(tmp_path, f"input={path}", "map.fps=null", "map.max_frames=10")
    with pytest.raises(TracksError, match=r"long\.npz: 50 frames to map, more than map\.max_"):
        map_from_config(config, config_dir=CONF)
    # within the cap, the same window is read
    window = rigmap.map.tracks.FrameWindow(count=10, max_frames=10)
    monkeypatch.setattr(rigmap.map.tracks, "check_memory", lambda *args: None)
    tracks = rigmap.map.tracks.read_tracks(path, unit="cm", window=window)
    assert tracks.positions.shape == (10, 2, 3)


@pytest.mark.parametrize(("threshold", "shown"), [(5, True), (8, False)])
def test_a_long_clip_shows_its_progress_on_stderr(
    mapped, project, monkeypatch, capsys, threshold, shown
):
    import rigmap.app.map_job

    monkeypatch.setattr(rigmap.app.map_job, "PROGRESS_FRAMES", threshold)
    config = map_config(
        project,
        f"input={WALK}",
        f"out={project / 'progress'}",
        "map.first_frame=240",
        "map.frames=8",
        "map.preview=false",
        "map.settings.refine_iterations=1",
    )
    (clip,) = map_from_config(config, config_dir=CONF, log=lambda line: None)
    err = capsys.readouterr().err
    assert clip.summary["frames"] == 8
    assert ("map cmu_131_01_walk (8 frames)" in err) is shown
    assert ("6/6" in err and "outputs" in err) is shown


ROOT = Path(__file__).resolve().parents[1]
ARCHITECTURE = ROOT / "docs" / "architecture.md"


def listed_places() -> list[str]:
    """The numbered ``module:function`` places of architecture.md's "Following `rigmap map`"."""
    import re

    text = ARCHITECTURE.read_text().split("## Following `rigmap map`", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\d+\. `(rigmap[\w.]*:[\w.]+)`", text, flags=re.MULTILINE)


def test_the_listed_path_of_rigmap_map_is_the_one_it_takes(mapped, project, tmp_path):
    """`rigmap map input=<bvh>` enters every listed place once, in the listed order (calls
    recorded with sys.setprofile), and the places are at most 10."""
    import importlib
    import sys

    places = listed_places()
    assert 5 <= len(places) <= 10 and len(set(places)) == len(places)
    for place in places:  # each names a real function
        module, _, qualname = place.partition(":")
        target = importlib.import_module(module)
        for part in qualname.split("."):
            target = getattr(target, part)
        assert callable(target), place
    src, calls = str(ROOT / "src" / "rigmap"), []

    def record(frame, event, arg):
        if event == "call" and frame.f_code.co_filename.startswith(src):
            calls.append(f"{frame.f_globals.get('__name__')}:{frame.f_code.co_qualname}")

    args = [
        "map",
        f"input={WALK}",
        "rig=biped",
        f"out={tmp_path / 'out'}",
        f"paths.data={project / 'data'}",
        f"paths.models={project / 'models'}",
        *SMALL_MODEL,
        "map.first_frame=240",
        "map.frames=8",
        "map.preview=false",
        "map.settings.refine_iterations=1",
    ]
    sys.setprofile(record)
    try:
        code = main(args)
    finally:
        sys.setprofile(None)
    assert code == 0 and (tmp_path / "out" / WALK.stem / "keys.json").is_file()
    assert [calls.count(p) for p in places] == [1] * len(places), places
    firsts = [calls.index(p) for p in places]
    assert firsts == sorted(firsts), [places[k] for k in np.argsort(firsts)]


def test_the_map_job_never_reads_back_what_it_wrote():
    """rigmap.app.map_job takes each clip's summary from the writer, not from summary.json."""
    import ast

    source = (ROOT / "src" / "rigmap" / "app" / "map_job.py").read_text()
    strings = [n.value for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Constant)]
    assert not [s for s in strings if isinstance(s, str) and "summary.json" in s]
    assert "read_text" not in source and "json.load" not in source
