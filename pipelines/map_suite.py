"""``make mocap-suite``: every clip of ``../shared/mocap/`` mapped whole onto a rig (issue #37).

Writes ``<paths.data>/<rig>/map_suite/<clip>/``, ``<paths.metrics>/<rig>/map_suite/<clip>.json``
and ``<paths.reports>/map_suite/<rig>.md``; the work is :mod:`rigmap.app.map_suite`.
It needs the rig's corpus and poses (the ``animate`` and ``pose`` stages).

    python pipelines/map_suite.py rig=biped
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rigmap.app.map_suite import map_suite
from rigmap.app.stage import run_stage

CONFIG_DIR = Path(__file__).resolve().parent.parent / "conf"


def run(cfg: DictConfig) -> Path:
    return map_suite(OmegaConf.to_container(cfg, resolve=True), config_dir=CONFIG_DIR)


if __name__ == "__main__":
    run_stage(run, config_name="map")
