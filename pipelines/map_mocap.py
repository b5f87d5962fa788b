"""DVC stage ``map_mocap``: the CMU walks of ``../shared/mocap/`` mapped onto a rig (§6.3, Fig. 8).

Reads the clips named in ``map.mocap_stage`` and the rig's train corpus and poses; fits
the map model into ``<paths.data>/<rig>/map/model/`` and writes, per clip,
``<paths.data>/<rig>/map/<clip>/`` (controls, keys, BVH, previews) and
``<paths.metrics>/<rig>/map/<clip>.{json,csv}``. The work is :mod:`rigmap.app.map_stage`.

    python pipelines/map_mocap.py rig=biped
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rigmap.app.map_stage import map_mocap
from rigmap.app.stage import run_stage

CONFIG_DIR = Path(__file__).resolve().parent.parent / "conf"


def run(cfg: DictConfig) -> list[Path]:
    return map_mocap(OmegaConf.to_container(cfg, resolve=True), config_dir=CONFIG_DIR)


if __name__ == "__main__":
    run_stage(run, config_name="map")
