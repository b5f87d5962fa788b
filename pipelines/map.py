"""``rigmap map`` as a Hydra app (not a DVC stage): sweeps with ``--multirun``.

    python pipelines/map.py input=../shared/mocap/cmu_131_01_walk.bvh rig=biped
    python pipelines/map.py --multirun input=../shared/mocap rig=biped \
        map.settings.refine_iterations=0,3

Takes the same overrides as ``rigmap map`` (conf/map.yaml); the work is
:func:`rigmap.app.map_job.map_from_config`.
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rigmap.app.map_job import MappedClip, map_from_config
from rigmap.app.stage import run_stage

CONFIG_DIR = Path(__file__).resolve().parent.parent / "conf"


def run(cfg: DictConfig) -> list[MappedClip]:
    return map_from_config(OmegaConf.to_container(cfg, resolve=True), config_dir=CONFIG_DIR)


if __name__ == "__main__":
    run_stage(run, config_name="map")
