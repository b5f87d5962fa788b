"""DVC stage ``animate``: a rig's motion library played into its train and test corpora.

Writes ``<paths.data>/<rig>/corpus/train.parquet`` and ``test.parquet`` (columns
``clip``, ``frame``, one per used control; rig, fps and seed in the file's metadata).
The same ``seed`` gives byte-identical files.

    python pipelines/animate.py rig=quadruped seed=0

A ``blend_file`` rig with ``rig.actions`` takes its corpus from the file's own actions
instead (:mod:`rigmap.animation.blend_corpus`; conf/rig/blend_file.yaml):

    python pipelines/animate.py rig=blend_file rig.path=/models/hero.blend rig.armature=rig
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from rigmap.animation.corpus_files import require_motion_library, write_corpora
from rigmap.app.inputs import corpus_settings, layout_of, rig_from_config
from rigmap.app.stage import run_stage


def run(cfg: DictConfig) -> list[Path]:
    if cfg.rig.get("actions") is not None:  # a user's .blend: its own actions are the corpus
        from omegaconf import OmegaConf

        from rigmap.animation.blend_corpus import write_blend_corpora

        options = OmegaConf.to_container(cfg.rig, resolve=True)
        return write_blend_corpora(options, options["actions"], layout_of(cfg))
    require_motion_library(cfg.rig.name)  # a rig without clips fails here, before it is built
    return write_corpora(rig_from_config(cfg.rig), layout_of(cfg), **corpus_settings(cfg))


if __name__ == "__main__":
    run_stage(run)
