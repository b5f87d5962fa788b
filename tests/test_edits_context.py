"""Context dependence (Fig 6) on real walk <-> stand transitions (issue #40).

Ikemoto et al.'s Fig 6: an edit made only while walking ("arms out while walking, down
while standing") is learned from examples with both, and a clip that starts and stops
gets arms that rise and fall with it. Here on real takes: subject 06 learned on 06_02
(stands, jogs, stops) and scored on 06_10 (go, stop, turn, go), through the stage commands.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from rigmap.cli import main
from rigmap.edits.procedural import Edit, EditConfigError
from rigmap.edits.study import edits_for

ROOT = Path(__file__).resolve().parents[1]
CONFIG = yaml.safe_load((ROOT / "conf/edits/default.yaml").read_text())
ARMS = yaml.safe_load((ROOT / "conf/edit/arms_forward_walking.yaml").read_text())


def test_a_subject_sets_the_walking_gate_of_its_edits():
    catalogue = {"arms_forward_walking": ARMS}
    spec = CONFIG["subjects"]["cmu_06"]
    (edit,) = edits_for(catalogue, ["arms_forward_walking"], "skeleton", spec, "cmu_06").values()
    assert edit.walking_speeds_cm_s == (20.0, 60.0)
    assert edit.operations[0].targets == ("LeftArm", "RightArm")  # and its joint aliases
    (default,) = edits_for(catalogue, ["arms_forward_walking"], "skeleton").values()
    assert default.walking_speeds_cm_s == (8.0, 20.0)  # the edit's own skeleton-mode gate


@pytest.mark.parametrize(
    "speeds, problem",
    [
        ([20.0], "expected two speeds"),
        (["slow", "fast"], "expected two speeds"),
        ("12", "expected two speeds"),  # a string is not read as (1, 2)
        ([True, 30.0], "expected two speeds"),
        ([60.0, 20.0], "expected 0 <= low < high"),
        ([-5.0, 20.0], "expected 0 <= low < high"),
        ([10.0, float("nan")], "expected 0 <= low < high"),
    ],
)
def test_a_bad_walking_gate_names_the_option(speeds, problem):
    spec = {"walking_speeds_cm_s": speeds}
    option = re.escape(f"edits.subjects.s.walking_speeds_cm_s: {problem}")
    with pytest.raises(EditConfigError, match=option):
        edits_for({"arms_forward_walking": ARMS}, ["arms_forward_walking"], "skeleton", spec, "s")


def test_the_walking_gate_follows_the_speeds():
    edit = Edit.from_config("arms_forward_walking", ARMS, "skeleton")
    track = _track_at_speeds(np.r_[np.full(60, 5.0), np.full(60, 40.0), np.full(60, 80.0)])
    default = edit.walking(track, 1.0)
    slower = edit.at_walking_speeds([20.0, 60.0], "x").walking(track, 1.0)
    # 40 cm/s walks under the edit's own gate (8-20) but is half way under 20-60
    assert default[90] == pytest.approx(1.0)
    assert slower[90] == pytest.approx(0.5, abs=0.02)
    assert default[10] == slower[10] == 0.0 and slower[170] == pytest.approx(1.0)


def test_arms_rise_and_fall_with_a_real_go_stop_turn_go(tmp_path):
    """End to end through the stage commands; the issue's bar is a correlation of at least
    0.7 (measured: 0.87 with the root speed, 0.89 with the ground truth)."""
    paths = [f"paths.{k}={tmp_path / k}" for k in ("models", "data", "metrics")]
    chosen = ["edits.run=[cmu_06]", "edits.names=[arms_forward_walking]", *paths]
    config = ["--config-dir", str(ROOT / "conf")]
    for verb in ("fit", "apply", "evaluate"):
        assert main(["edits", verb, *config, *chosen]) == 0
    folder = tmp_path / "metrics/cmu_06/edits"
    context = json.loads((folder / "summary.json").read_text())["arms_forward_walking"]["context"]
    assert context["correlation_with_speed"] >= 0.7
    assert context["correlation_with_truth"] >= 0.7
    bands = {tuple(b["speed_cm_s"]): b for b in context["bands"]}
    standing, walking = bands[(10.0, 20.0)], bands[(80.0, None)]  # JSON has no infinity
    assert standing["frames"] > 200 and walking["frames"] > 200
    assert walking["predicted_fraction"] > standing["predicted_fraction"] + 0.4
    with (folder / "edits.csv").open() as stream:
        (row,) = csv.DictReader(stream)
    assert float(row["context_correlation_with_speed"]) == pytest.approx(
        context["correlation_with_speed"], rel=1e-5
    )


def _track_at_speeds(speeds_cm_s: np.ndarray):
    """A track whose root moves forward at these speeds (1 cm per unit), nothing else."""
    from rigmap.edits.representation import ROOT_CHANNELS, TargetTrack

    fps = 30.0
    values = np.zeros((len(speeds_cm_s), len(ROOT_CHANNELS)))
    values[:, 0] = 1.0 / fps  # dt
    values[:, 1] = speeds_cm_s / fps  # root.step_forward
    return TargetTrack(ROOT_CHANNELS, values, fps, (0.0, 0.0, 0.0), source="speeds")
