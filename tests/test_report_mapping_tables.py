"""The report's mapping tables read what the map_mocap and map_partial stages write."""

from __future__ import annotations

import json

import pandas as pd

from rigmap.reports.mapping_tables import mocap_table, partial_table


def test_mapping_tables_show_the_stage_metrics_and_are_absent_without_them(tmp_path):
    assert mocap_table(tmp_path) is None and partial_table(tmp_path) is None
    (tmp_path / "biped" / "map").mkdir(parents=True)
    record = {"rig": "biped", "source": "../shared/mocap/cmu_131_01_walk.bvh", "frames": 16,
              "joint_error_rms_cm": 4.278, "joint_error_rms_percent_of_height": 2.397,
              "largest_jump_training_std": 2.127, "foot_skate_result_cm_per_frame": 1.336,
              "foot_skate_source_cm_per_frame": 0.221, "keys": 1116,
              "frames_times_keyed_controls": 3376, "frames_per_second": 9.77}  # fmt: skip
    (tmp_path / "biped" / "map" / "cmu_131_01_walk.json").write_text(json.dumps(record))
    table = mocap_table(tmp_path)
    assert table.rows == [["Biped", "cmu_131_01_walk", "16", "4.28 (2.40 %)", "2.13",
                           "1.34 / 0.22", "1116 / 3376", "9.77"]]  # fmt: skip
    assert "mocap.cs.cmu.edu" in table.notes[0]
    (tmp_path / "quadruped" / "map_partial").mkdir(parents=True)
    pd.DataFrame({"rig": ["quadruped"] * 2, "subset": ["full", "feet"], "given_joints": [76, 4],
                  "stage": ["refined"] * 2, "frames": [57, 57], "given_error_cm": [3.4569, 4.25835],
                  "body_error_cm": [3.4569, 26.5665], "ground_truth_error": [3.7999, 3.85856],
                  "seconds": [1.4, 2.1]}).to_csv(tmp_path / "quadruped" / "map_partial" /
                                                 "partial_inputs.csv", index=False)  # fmt: skip
    partial = partial_table(tmp_path)
    assert partial.rows[1] == ["Quadruped", "feet (4 joints)", "refined", "57", "4.26", "26.57",
                               "3.46", "3.86"]  # fmt: skip
    assert partial.title == "Partial input: feet only (Fig. 6) beside the full joints"
    assert len(partial.notes) == 1  # no subset of the quadruped is every joint


def test_face_ik_rows_say_the_landmarks_are_every_joint(tmp_path):
    rows = []
    for subset in ("full", "landmarks"):
        for stage, frames, error in (("guess", 168, 0.6486), ("refined", 42, 0.4625)):
            rows.append({"rig": "face", "subset": subset, "given_joints": 6, "stage": stage,
                         "frames": frames, "given_error_cm": error, "body_error_cm": error,
                         "ground_truth_error": 4.2, "seconds": 0.1})  # fmt: skip
    (tmp_path / "face" / "map_partial").mkdir(parents=True)
    pd.DataFrame(rows).to_csv(tmp_path / "face" / "map_partial" / "partial_inputs.csv", index=False)
    table = partial_table(tmp_path)
    assert table.title == "Partial input: FaceIK landmarks (Fig. 10) beside the full joints"
    assert table.rows[3] == ["Face", "landmarks (6 joints)", "refined", "42", "0.46", "0.46",
                             "0.46", "4.20"]  # fmt: skip
    assert table.notes[1].startswith("Face: its landmarks are all 6 of its joints")
    assert list(table.data["full_input_body_error_cm"]) == [0.6486, 0.4625] * 2
