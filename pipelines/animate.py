"""DVC stage ``animate``: a rig's motion library played into its train and test corpora.

Writes ``<paths.data>/<rig>/corpus/train.parquet`` and ``test.parquet`` (columns
``clip``, ``frame``, one per used control; rig, fps and seed in the file's metadata).
The same ``seed`` gives byte-identical files.

    python pipelines/animate.py rig=quadruped seed=0
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from rigmap.animation.corpus_files import require_motion_library, write_corpora
from rigmap.stage import run_stage
from rigmap.stage.inputs import corpus_settings, layout_of, rig_from_config


def run(cfg: DictConfig) -> list[Path]:
    require_motion_library(cfg.rig.name)  # a rig without clips fails here, before it is built
    return write_corpora(rig_from_config(cfg.rig), layout_of(cfg), **corpus_settings(cfg))


if __name__ == "__main__":
    run_stage(run)
