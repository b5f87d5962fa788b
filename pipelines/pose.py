"""DVC stage ``pose``: the rig evaluated on every frame of its train and test corpora.

Reads ``<paths.data>/<rig>/corpus/{train,test}.parquet`` and writes
``<paths.data>/<rig>/poses/{train,test}.parquet``: ``clip``, ``frame``, joint positions
relative to the COG (cm) and the COG's world placement.

    python pipelines/pose.py rig=quadruped
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from rigmap.animation.corpus_files import pose_corpora
from rigmap.app.inputs import layout_of, rig_from_config
from rigmap.app.stage import run_stage


def run(cfg: DictConfig, *, progress: bool = True) -> list[Path]:
    rig = rig_from_config(cfg.rig, cfg.get("executor"))
    return pose_corpora(rig, layout_of(cfg), batch_size=int(cfg.pose.batch_size), progress=progress)


if __name__ == "__main__":
    run_stage(run)
