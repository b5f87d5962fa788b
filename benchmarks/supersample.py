"""Seconds to draw and pose 100 000 samples per strategy (issue: < 60 s for pca_gaussian).

Prints JSON. For every strategy: fitting on the corpus, drawing the vectors
alone, and the whole ``supersample`` run (draw, clamp, pose in chunks, save
chunks, write the final npz) into a temporary folder. The corpus is the
rig's training corpus (``data/<rig>/corpus/train.parquet``) when it exists,
otherwise a synthetic one (smooth correlated motion of the used controls).

    .venv/bin/python benchmarks/supersample.py [--rig quadruped] [--n 100000]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from rigmap.rigs import load
from rigmap.sampling import available, make_sampler, supersample

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rig", default="quadruped")
    parser.add_argument("--n", type=int, default=100_000, help="samples per strategy")
    parser.add_argument("--chunk-size", type=int, default=10_000)
    parser.add_argument("--samplers", nargs="+", default=available(), choices=available())
    parser.add_argument("--corpus", type=Path, help="corpus parquet (default: the rig's train)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)

    load_before = os.getloadavg()[0]  # other processes share the cores; say so
    started = time.perf_counter()
    rig = load(args.rig)
    load_s = time.perf_counter() - started
    corpus, source = training_corpus(rig, args.corpus)
    results = {}
    with tempfile.TemporaryDirectory(prefix="supersample-bench-") as tmp:
        for name in args.samplers:
            results[name] = measure(rig, name, corpus, args, Path(tmp))
            print(f"{name}: {results[name]}", file=sys.stderr)
    report = {
        "benchmark": "supersample",
        "rig": rig.name,
        "n": args.n,
        "chunk_size": args.chunk_size,
        "cpus": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "rig_load_s": round(load_s, 3),
        "load_average_1min_before": round(load_before, 2),
        "corpus": {"source": source, "frames": int(corpus.shape[0]), "controls": corpus.shape[1]},
        "target": "pca_gaussian supersample_s < 60 on 2 cores",
        "samplers": results,
        "load_average_1min_after": round(os.getloadavg()[0], 2),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }
    print(json.dumps(report, indent=2))


class TimedRig:
    """The rig, with the seconds spent inside ``pose`` added up (the rest is the runner's)."""

    def __init__(self, rig):
        self._rig = rig
        self.pose_s = 0.0

    def __getattr__(self, name):
        return getattr(self._rig, name)

    def pose(self, Y):
        started = time.perf_counter()
        try:
            return self._rig.pose(Y)
        finally:
            self.pose_s += time.perf_counter() - started


def measure(rig, name: str, corpus: np.ndarray, args, folder: Path) -> dict:
    sampler = make_sampler(name)
    started = time.perf_counter()
    sampler.fit(corpus)
    fit_s = time.perf_counter() - started

    started = time.perf_counter()
    drawn = sampler.sample(args.n, np.random.default_rng(args.seed))
    draw_s = time.perf_counter() - started
    del drawn

    path = folder / f"{name}.npz"
    timed = TimedRig(rig)
    started = time.perf_counter()
    result = supersample(
        timed, sampler, args.n, path, seed=args.seed, chunk_size=args.chunk_size, progress=False
    )
    supersample_s = time.perf_counter() - started
    size_mb = path.stat().st_size / 1e6
    path.unlink()
    return {
        "fit_s": round(fit_s, 3),
        "draw_s": round(draw_s, 3),
        "supersample_s": round(supersample_s, 3),
        "of_which_rig_pose_s": round(timed.pose_s, 3),
        "samples_per_s": round(result.n_samples / supersample_s, 1) if result.n_samples else None,
        "n_samples": result.n_samples,
        "n_clamped_values": result.n_clamped,
        "n_clamped_rows": result.n_rows_clamped,
        "file_mb": round(size_mb, 1),
    }


def training_corpus(rig, path: Path | None) -> tuple[np.ndarray, str]:
    """Used-control values of the rig's training corpus, or a synthetic stand-in."""
    path = path or ROOT / "data" / rig.name / "corpus" / "train.parquet"
    if path.is_file():
        from rigmap.animation.corpus import read_corpus

        table, _ = read_corpus(path, rig=rig.name, control_names=rig.used_controls)
        return table[rig.used_controls].to_numpy(dtype=np.float64), str(path.relative_to(ROOT))
    return synthetic_corpus(rig), "synthetic (no corpus file yet)"


def synthetic_corpus(rig, frames: int = 1_000, factors: int = 8) -> np.ndarray:
    """Smooth motion: a few slow latent signals mixed into every used control.

    Only a stand-in for timing: it has the corpus's size and low rank, not an
    animator's poses.
    """
    rng = np.random.default_rng(0)
    used = rig.controls.used_indices
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    time_s = np.arange(frames) / 30.0
    frequencies = rng.uniform(0.2, 2.0, size=factors)
    phases = rng.uniform(0, 2 * np.pi, size=factors)
    latent = np.sin(time_s[:, None] * 2 * np.pi * frequencies + phases)
    mixing = rng.normal(size=(factors, used.size)) / np.sqrt(factors)
    motion = rig.controls.defaults[used] + 0.15 * (upper - lower) * (latent @ mixing)
    return np.clip(motion, lower, upper)


if __name__ == "__main__":
    main()
