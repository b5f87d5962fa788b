"""DVC stage ``map_partial``: the rig posed from a few joints, and a joint-space edit mapped back.

Reads ``<paths.data>/<rig>/{corpus,poses}/{train,test}.parquet``; fits a subset mapping (the
``regressor`` group) per input of ``map_partial.input_joints`` (null: every subset of the
rig's) plus the full joint set, scores them on the test clips and, for a rig with
``map_partial.edit_joints``, maps the motion-editing demo (paper §6.3, Figs 5-7 and 10);
writes ``<paths.metrics>/<rig>/map_partial/{partial_inputs.json,partial_inputs.csv}`` and
``motion_edit.json`` with a demo (:mod:`rigmap.app.map_partial`).

    python pipelines/map_partial.py rig=biped regressor=gpr kernel=multiquadric
    python pipelines/map_partial.py rig=face regressor=gpr kernel=multiquadric   # FaceIK
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rigmap.app.map_partial import map_partial_from_config
from rigmap.app.stage import run_stage


def run(cfg: DictConfig) -> list[Path]:
    return map_partial_from_config(OmegaConf.to_container(cfg, resolve=True))


if __name__ == "__main__":
    run_stage(run)
