"""DVC stage ``sample_figures``: the paper's Fig. 4 for one rig, from the supersample files.

Reads ``<paths.data>/<rig>/samples/<sampler>.npz`` for every strategy and the train
corpus, and writes ``<paths.reports>/figures/samples_<rig>.png``: one row per strategy
(the corpus first, standing for ``none``), a few random samples each, drawn as poses.

    python pipelines/sample_figures.py rig=quadruped
    python pipelines/sample_figures.py rig=face figures.per_row=8 figures.view=side
"""

from __future__ import annotations

from contextlib import ExitStack

import numpy as np
from omegaconf import DictConfig, OmegaConf

from rigmap.animation.corpus_files import read_corpus_split
from rigmap.app.inputs import layout_of, rig_from_config
from rigmap.app.stage import run_stage
from rigmap.rigs.manifest import manifest
from rigmap.sampling import available
from rigmap.viz.samples import SampleFigure, draw_sample_figure, sample_rows

# The view each rig's poses read best in is its manifest's ``view`` (the face's
# expressions show from the front, the others from the side). Override with figures.view=...


def run(cfg: DictConfig) -> SampleFigure:
    rig = rig_from_config(cfg.rig)
    layout = layout_of(cfg)
    corpus = read_corpus_split(rig, layout, "train")
    paths = {name: layout.samples(rig.name, name) for name in available()}
    for name, path in paths.items():
        if not path.is_file():
            raise FileNotFoundError(
                f"{path} does not exist; run `python pipelines/supersample.py rig={rig.name} "
                f"sampler={name}` (or `dvc repro supersample`) first"
            )
    with ExitStack() as files:
        # opened lazily: only the arrays a row needs are read (paper-size files are GBs)
        samples = {name: files.enter_context(np.load(path)) for name, path in paths.items()}
        rows = sample_rows(
            rig,
            samples,
            corpus.values(),
            per_row=int(OmegaConf.select(cfg, "figures.per_row", default=6)),
            rng=np.random.default_rng(int(cfg.seed)),
        )
    figure = draw_sample_figure(
        rig,
        rows,
        layout.figures() / f"samples_{rig.name}.png",
        view=OmegaConf.select(cfg, "figures.view", default=manifest(rig.name).view),
    )
    print(f"{rig.name}: {len(figure.rows)} rows ({figure.view} view) -> {figure.path}")
    return figure


if __name__ == "__main__":
    run_stage(run)
