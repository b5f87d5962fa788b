"""DVC stage ``map_path``: a walk bent along a quarter circle over a slope, mapped (§6.3, Fig. 7).

Reads ``<paths.data>/<rig>/{corpus,poses}/train.parquet`` and ``conf/map_path/`` (the stage
file and its path); writes ``<paths.data>/<rig>/map_path/`` (the mapped clip and its map
model), ``<paths.metrics>/<rig>/map_path/<name>.{json,csv}`` and
``<paths.reports>/figures/map_path_<rig>.png``. The work is :mod:`rigmap.app.map_path`.

    python pipelines/map_path.py rig=biped
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rigmap.app.map_path import map_path
from rigmap.app.stage import run_stage

CONFIG_DIR = Path(__file__).resolve().parent.parent / "conf"


def run(cfg: DictConfig) -> list[Path]:
    return map_path(OmegaConf.to_container(cfg, resolve=True), config_dir=CONFIG_DIR)


if __name__ == "__main__":
    run_stage(run, config_name="map")
