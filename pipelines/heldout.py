"""DVC stage ``heldout``: new takes of the training motions, posed — the in-distribution test set.

The library's test clips are extreme on purpose (issue #15: most of their frames lie far
outside the corpus); this set asks the other question, how well a mapping does on motion
like its training motion. Writes ``<paths.data>/<rig>/heldout/{corpus,poses}.parquet``:
the train split's motions played with another seed (``HELDOUT_SEED_OFFSET``), each
keeping its training take's sides unless ``corpus.heldout_sides=drawn``.

    python pipelines/heldout.py rig=quadruped seed=0
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from rigmap.animation.corpus_files import write_heldout
from rigmap.app.inputs import corpus_settings, layout_of, rig_from_config
from rigmap.app.stage import run_stage


def run(cfg: DictConfig) -> list[Path]:
    rig, layout = rig_from_config(cfg.rig), layout_of(cfg)
    return write_heldout(
        rig,
        layout,
        batch_size=int(cfg.pose.batch_size),
        heldout_sides=str(cfg.corpus.heldout_sides),
        **corpus_settings(cfg),
    )


if __name__ == "__main__":
    run_stage(run)
