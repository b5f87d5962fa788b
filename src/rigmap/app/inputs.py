"""The plain objects a stage builds from its composed config, so the library never sees one.

A stage (``pipelines/*.py``) composes its config with Hydra, turns it into these objects
— the :class:`~rigmap.store.Layout` of its files, the rig, the unfitted sampler and its
seed — and hands them to one library function.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from rigmap.store import Layout

__all__ = [
    "corpus_fps",
    "corpus_settings",
    "layout_of",
    "rig_from_config",
    "sampler_from_config",
    "sampler_seed",
]

DEFAULT_FPS = 24  # the frame rate a rig config without ``corpus.fps`` is played at


def layout_of(cfg: DictConfig) -> Layout:
    """The experiment's folders, from the ``paths`` config."""
    return Layout.from_paths(OmegaConf.to_container(cfg.paths, resolve=True))


def rig_from_config(rig_cfg: DictConfig, executor: DictConfig | None = None):
    """The rig named by the ``rig`` group (its ``corpus`` options are not the factory's),
    evaluated on the ``executor`` group's engine (``local`` or ``ray``)."""
    from rigmap.rigs import load, use_executor

    options = OmegaConf.to_container(rig_cfg, resolve=True)
    options.pop("corpus", None)
    rig = load(options)
    if executor is not None:
        use_executor(rig, OmegaConf.to_container(executor, resolve=True))
    return rig


def corpus_fps(rig_cfg: DictConfig) -> int:
    """The frame rate the rig's corpus is played at (``rig.corpus.fps``)."""
    return int((rig_cfg.get("corpus") or {}).get("fps", DEFAULT_FPS))


def corpus_settings(cfg: DictConfig) -> dict[str, Any]:
    """How the motion library is played: ``seed``, ``fps`` and ``variation`` keywords of
    :func:`rigmap.animation.corpus_files.write_corpora` and ``write_heldout``."""
    return {
        "seed": int(cfg.seed),
        "fps": corpus_fps(cfg.rig),
        "variation": float(cfg.corpus.variation),
    }


def sampler_from_config(sampler_cfg: DictConfig, rig) -> Any:
    """The unfitted sampler; ``uniform`` with ``range: soft`` gets the rig's soft range."""
    from rigmap.app.objects import instantiate_sampler, sampler_name

    options = OmegaConf.to_container(sampler_cfg, resolve=True)
    overrides = {}
    if sampler_name(options) == "uniform" and options.get("range") == "soft":
        used = rig.controls.used_indices
        if options.get("lower") is None:
            overrides["lower"] = rig.controls.lower[used]
        if options.get("upper") is None:
            overrides["upper"] = rig.controls.upper[used]
    return instantiate_sampler(options, **overrides)


def sampler_seed(seed: int, sampler_name: str) -> int:
    """The draw's seed: the run's ``seed`` mixed with the strategy name (stable across runs).

    Two strategies run with the same ``seed`` then do not share their random numbers.
    """
    entropy = [int(seed), zlib.crc32(sampler_name.encode("utf-8"))]
    return int(np.random.SeedSequence(entropy).generate_state(1, dtype=np.uint32)[0])
