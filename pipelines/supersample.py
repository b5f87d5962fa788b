"""DVC stage ``supersample``: extra control vectors around a rig's corpus, posed by the rig (§5.2).

Fits the configured sampler (``conf/sampler/*.yaml``) on the used-control values of
``<paths.data>/<rig>/corpus/train.parquet``, draws ``budget.samples`` vectors, clamps them
to the rig's control ranges, poses them in chunks and writes
``<paths.data>/<rig>/samples/<sampler>.npz`` (see ``rigmap.sampling.supersample``).
A killed run resumes from the finished chunks in ``<sampler>.chunks/`` beside the file.

    python pipelines/supersample.py rig=quadruped sampler=gmm
    python pipelines/supersample.py rig=face sampler=uniform sampler.range=soft budget.samples=20000
    python pipelines/supersample.py rig=biped supersample.chunk_size=2000

The draw is seeded from ``seed`` and the sampler's name together, so two strategies
run with the same ``seed`` do not share their random numbers.
"""

from __future__ import annotations

import time

from omegaconf import DictConfig, OmegaConf

from rigmap.animation.corpus_files import read_corpus_split
from rigmap.app.inputs import layout_of, rig_from_config, sampler_from_config, sampler_seed
from rigmap.app.stage import run_stage
from rigmap.sampling import SupersampleResult, supersample
from rigmap.sampling.supersample import DEFAULT_CHUNK_SIZE, check_supersample_memory


def run(cfg: DictConfig, *, progress: bool = True) -> SupersampleResult:
    rig = rig_from_config(cfg.rig, cfg.get("executor"))
    layout = layout_of(cfg)
    check_supersample_memory(rig, int(cfg.budget.samples), "budget.samples")  # before any work
    corpus = read_corpus_split(rig, layout, "train")
    started = time.perf_counter()
    sampler = sampler_from_config(cfg.sampler, rig).fit(corpus.values())
    fitted = time.perf_counter()
    result = supersample(
        rig,
        sampler,
        int(cfg.budget.samples),
        layout.samples(rig.name, sampler.name),
        seed=sampler_seed(int(cfg.seed), sampler.name),
        chunk_size=int(OmegaConf.select(cfg, "supersample.chunk_size", default=DEFAULT_CHUNK_SIZE)),
        progress=progress,
        option="budget.samples",
    )
    n_values = result.n_samples * len(rig.used_controls)
    share = f" ({result.n_rows_clamped / result.n_samples:.1%} of samples)" if n_values else ""
    print(
        f"{rig.name} {sampler.name}: {result.n_samples} samples from {len(corpus.table)} corpus "
        f"frames; clamped {result.n_clamped} of {n_values} control values in "
        f"{result.n_rows_clamped} samples{share}; {result.chunks_evaluated} chunks posed, "
        f"{result.chunks_resumed} resumed; fit {fitted - started:.1f} s, draw and pose "
        f"{time.perf_counter() - fitted:.1f} s -> {result.path}"
    )
    return result


if __name__ == "__main__":
    run_stage(run)
