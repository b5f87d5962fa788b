"""Samplers by name, so configs and the command line can choose a strategy."""

from __future__ import annotations

import importlib

from rigmap.sampling.base import Sampler
from rigmap.sampling.gmm import GaussianMixtureSampler
from rigmap.sampling.multivariate_gaussian import MultivariateGaussianSampler
from rigmap.sampling.none import NoExtraSamples
from rigmap.sampling.pca_gaussian import PCAGaussianSampler
from rigmap.sampling.uniform import UniformSampler
from rigmap.sampling.univariate_gaussian import UnivariateGaussianSampler

SAMPLERS: dict[str, type[Sampler]] = {
    cls.name: cls
    for cls in (
        NoExtraSamples,
        UniformSampler,
        UnivariateGaussianSampler,
        MultivariateGaussianSampler,
        GaussianMixtureSampler,
        PCAGaussianSampler,
    )
}


def available() -> list[str]:
    """Strategy names in the order of the paper's Table 2."""
    return list(SAMPLERS)


def make_sampler(name: str, **hyper_parameters) -> Sampler:
    """An unfitted sampler of strategy ``name``.

    Accepts a whole ``conf/sampler/*.yaml`` node too: ``make_sampler(**cfg.sampler)``.
    Its ``_target_`` (what ``hydra.utils.instantiate`` would call) must be the
    class registered under ``name``; it is checked, then dropped, because
    ``instantiate`` would also pass ``name`` on to the class.
    """
    if name not in SAMPLERS:
        raise KeyError(f"unknown sampler {name!r}; available samplers: {', '.join(SAMPLERS)}")
    cls = SAMPLERS[name]
    target = hyper_parameters.pop("_target_", None)
    if target is not None and _resolve(target) is not cls:
        raise ValueError(
            f"sampler config {name!r}: _target_ {target!r} is not {cls.__module__}.{cls.__name__}"
        )
    options = {k: _plain(v) for k, v in hyper_parameters.items() if not k.startswith("_")}
    try:
        return cls(**options)
    except TypeError as error:
        raise TypeError(f"sampler {name!r} ({cls.__name__}): {error}") from None


def _resolve(target: str):
    module, _, attribute = target.rpartition(".")
    try:
        return getattr(importlib.import_module(module), attribute)
    except (ImportError, AttributeError, ValueError):
        return None


def _plain(value):
    """OmegaConf lists and dicts as plain Python, so samplers see lists and numbers."""
    try:
        from omegaconf import DictConfig, ListConfig, OmegaConf
    except ImportError:  # pragma: no cover - omegaconf is a dependency
        return value
    if isinstance(value, DictConfig | ListConfig):
        return OmegaConf.to_container(value, resolve=True)
    return value
