"""The report's Fig. 7 table and figure (``rigmap.reports.path_tables``): present when the
``map_path`` stage wrote its metrics, absent (no table, no figure, no error) otherwise; and
``rigmap map`` names a bad ``map.path`` before it reads any input."""

from __future__ import annotations

import json

import pytest

from rigmap.app.map_job import map_from_config
from rigmap.app.map_path_options import PathOptionError
from rigmap.reports.path_tables import path_figures, path_table

SCORES = {
    "bent_only": {
        "foot_skate_cm_per_frame": 1.6,
        "penetration_max_cm": 31.8,
        "penetration_mean_cm": 15.4,
    },
    "edited": {
        "foot_skate_cm_per_frame": 0.0,
        "penetration_max_cm": 1.05,
        "penetration_mean_cm": 0.06,
    },
    "mapped": {
        "foot_skate_cm_per_frame": 0.47,
        "penetration_max_cm": 2.92,
        "penetration_mean_cm": 0.33,
        "joint_error_rms_cm": 1.78,
    },
}


def test_the_table_and_figure_appear_when_the_stage_ran(tmp_path):
    folder = tmp_path / "metrics" / "biped" / "map_path"
    folder.mkdir(parents=True)
    record = {"rig": "biped", "terrain": "slope", "frames": 144, "scores": SCORES}
    (folder / "walk.json").write_text(json.dumps(record))
    figures = tmp_path / "figures"
    figures.mkdir()
    (figures / "map_path_biped.png").write_bytes(b"png")
    table = path_table(tmp_path / "metrics")
    assert [row[2] for row in table.rows] == [
        "bent only (flat, feet free)",
        "edited: feet held, on the terrain",
        "the rig, mapped",
    ]
    assert table.rows[2][3:] == ["0.47", "2.92 / 0.33", "1.78"]
    assert table.data.loc[2, "joint_error_rms_cm"] == pytest.approx(1.78)
    assert [f.path.name for f in path_figures(figures)] == ["map_path_biped.png"]


def test_nothing_appears_when_the_stage_did_not_run(tmp_path):
    assert path_table(tmp_path) is None
    assert path_figures(tmp_path) == []


def test_rigmap_map_names_a_bad_path_before_reading_input(tmp_path):
    config = {"rig": {"name": "biped"}, "input": None, "map": {"path": str(tmp_path / "no.yaml")}}
    with pytest.raises(PathOptionError, match=r"^map\.path: path file .* does not exist$"):
        map_from_config(config, config_dir=tmp_path)
