"""DVC stage ``animate``: a rig's motion library played into its train and test corpora.

Writes ``<paths.data>/<rig>/corpus/train.parquet`` and ``test.parquet`` (columns
``clip``, ``frame``, one per used control; rig, fps and seed in the file's metadata).
The same ``seed`` gives byte-identical files.

    python pipelines/animate.py rig=quadruped seed=0
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rigmap.animation.library import SPLITS, Variation, build_corpus, motion_library
from rigmap.rigs import load
from rigmap.stage import run_stage


def rig_from_config(rig_cfg: DictConfig):
    """The rig named by the ``rig`` group (its ``corpus`` options are not the factory's)."""
    options = OmegaConf.to_container(rig_cfg, resolve=True)
    options.pop("corpus", None)
    return load(options)


def run(cfg: DictConfig) -> list[Path]:
    motion_library(cfg.rig.name)  # a rig without clips fails here, before it is built
    rig = rig_from_config(cfg.rig)
    corpus_options = cfg.rig.get("corpus") or {}
    variation = Variation().scaled(float(cfg.corpus.variation))
    out = Path(cfg.paths.data) / rig.name / "corpus"
    written = []
    for split in SPLITS:
        corpus = build_corpus(
            rig,
            split,
            seed=int(cfg.seed),
            fps=int(corpus_options.get("fps", 24)),
            variation=variation,
        )
        written.append(corpus.write(out / f"{split}.parquet"))
        meta = corpus.metadata
        print(
            f"{rig.name} {split}: {len(meta['clips'])} clips, {meta['frame_count']} frames at "
            f"{meta['fps']} fps, {meta['keyed_frame_count']} keyed frames -> {written[-1]}"
        )
    return written


if __name__ == "__main__":
    run_stage(run)
