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
    pd.DataFrame({"rig": ["quadruped"], "subset": ["feet"], "given_joints": [4],
                  "stage": ["refined"], "frames": [57], "given_error_cm": [4.25835],
                  "body_error_cm": [26.5665], "ground_truth_error": [3.85856],
                  "seconds": [2.1]}).to_csv(tmp_path / "quadruped" / "map_partial" /
                                            "partial_inputs.csv", index=False)  # fmt: skip
    partial = partial_table(tmp_path)
    assert partial.rows == [["Quadruped", "feet (4 joints)", "refined", "57", "4.26", "26.57",
                             "3.86"]]  # fmt: skip
