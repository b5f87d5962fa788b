"""The real-mocap suite (rigmap.app.map_suite) on one short whole clip, and its page."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rigmap.app.map_suite import SuiteError, map_suite, suite_clips, suite_page
from rigmap.cli import compose_config, find_config_dir

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "mocap"
CONF = find_config_dir(Path(__file__).resolve().parents[1] / "conf")
SMALL_MODEL = [
    "budget.gpr_points=80",
    "budget.length_scales=3",
    "budget.cv_splits=2",
    "budget.refine_iterations=1",
]


@pytest.fixture(scope="module")
def project(tmp_path_factory, biped):
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("suite")
    layout = Layout(data=root / "data", models=root / "models")
    write_corpora(biped, layout, seed=0, fps=24, variation=1.0)
    pose_corpora(biped, layout, batch_size=512, progress=False)
    return root


def suite_config(project: Path, *overrides: str) -> dict:
    from omegaconf import OmegaConf

    from rigmap.app.stage import stage_config

    paths = [f"paths.{p}={project / p}" for p in ("data", "models", "metrics", "reports")]
    cfg = compose_config(["rig=biped", *paths, *SMALL_MODEL, *overrides], CONF, config_name="map")
    return OmegaConf.to_container(stage_config(cfg), resolve=True)


def test_the_suite_maps_a_whole_clip_of_the_other_conversion_and_writes_its_page(project):
    # the run: 149 source frames of Hahne's conversion (skeleton matched, T-pose cut)
    clips = "map.mocap_suite.clips=[cmu_09_01]"
    config = suite_config(project, f"map.mocap_suite.folder={MOCAP}", clips)
    page = map_suite(config, config_dir=CONF, log=lambda line: None)
    metrics = json.loads((project / "metrics/biped/map_suite/cmu_09_01.json").read_text())
    assert metrics["kind"] == "run"
    assert metrics["frames"] == 37  # 148 captured frames at 120 fps, every 4th
    assert metrics["euler_flips"] == 0
    assert metrics["contact_slip_max_cm"] <= 0.1
    assert 0 < metrics["keys_per_frame_and_control"] < 1
    # beside the report, not in reports/tables/, which the report stage replaces whole
    assert page == project / "reports" / "map_suite" / "biped.md"
    text = page.read_text()
    assert "| cmu_09_01 | run | 37 |" in text
    assert "mocap.cs.cmu.edu" in text and "of 1 clips" in text


def test_suite_clips_and_page_on_bad_input(tmp_path):
    with pytest.raises(SuiteError, match="no clips to map"):
        suite_clips({"folder": str(tmp_path)})
    with pytest.raises(SuiteError, match="missing"):
        suite_clips({"folder": str(MOCAP), "clips": ["cmu_99_99"]})
    assert len(suite_clips({"folder": str(MOCAP)})) == 19
    row = {
        "clip": "a",
        "kind": "walk",
        "frames": 10,
        "joint_error_rms_cm": 2.0,
        "joint_error_rms_percent_of_height": 1.1,
        "foot_skate_result_cm_per_frame": 0.01,
        "foot_skate_source_cm_per_frame": 0.3,
        "ground_penetration_result_cm": 1.0,
        "ground_penetration_source_cm": 2.0,
        "largest_jump_training_std": 6.0,
        "keys_per_frame_and_control": 0.1,
        "euler_flips": 0,
        "frames_per_second": 5.0,
    }
    page = suite_page("biped", [row])
    assert "joint_error_rms_cm <= 1.5: 0 of 1 clips" in page
    assert "largest_jump_training_std <= 5.0: 0 of 1 clips" in page
    assert "keys_per_frame_and_control <= 0.15: 1 of 1 clips" in page
    assert "skate no more than the source's: 1 of 1 clips" in page
