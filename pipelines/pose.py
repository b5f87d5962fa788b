"""DVC stage ``pose``: the rig evaluated on every frame of its train and test corpora.

Reads ``<paths.data>/<rig>/corpus/{train,test}.parquet`` and writes
``<paths.data>/<rig>/poses/{train,test}.parquet``: ``clip``, ``frame``, joint positions
relative to the COG (cm) and the COG's world placement.

    python pipelines/pose.py rig=quadruped
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig

from animate import rig_from_config
from rigmap.animation.corpus import Corpus
from rigmap.animation.library import SPLITS
from rigmap.animation.posing import pose_corpus
from rigmap.stage import run_stage


def run(cfg: DictConfig, *, progress: bool = True) -> list[Path]:
    rig = rig_from_config(cfg.rig)
    data = Path(cfg.paths.data) / rig.name
    written = []
    for split in SPLITS:
        source = data / "corpus" / f"{split}.parquet"
        corpus = Corpus.read(source, rig=rig.name, control_names=rig.used_controls, split=split)
        poses = pose_corpus(
            rig,
            corpus,
            batch_size=int(cfg.pose.batch_size),
            progress=progress,
            source=source.as_posix(),
        )
        written.append(poses.write(data / "poses" / f"{split}.parquet"))
        print(
            f"{rig.name} {split}: {len(poses.table)} frames, {poses.n_joints} joints "
            f"-> {written[-1]}"
        )
    return written


if __name__ == "__main__":
    run_stage(run)
