"""Samplers from their configs, and the names of the built-in ones.

A sampler is built like every other part: ``hydra.utils.instantiate`` on its
``conf/sampler/*.yaml`` node, whose ``_target_`` is the class; the class knows
its own ``name``, so the yaml does not restate it (:func:`sampler_name` reads
it from the class without building anything). A new strategy is one class plus
one yaml file.

``make_sampler``, ``SAMPLERS`` and ``available`` are kept for callers that
choose a strategy by name (the command line, benchmarks, figures): they are
derived from the sampler classes themselves, not kept as a second list.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rigmap.config_objects import instantiate_as
from rigmap.sampling.base import Sampler, SamplerInputError, sampler_classes

# importing the strategies makes them subclasses of Sampler (the names below come from them)
from rigmap.sampling.gmm import GaussianMixtureSampler  # noqa: F401
from rigmap.sampling.multivariate_gaussian import MultivariateGaussianSampler  # noqa: F401
from rigmap.sampling.none import NoExtraSamples  # noqa: F401
from rigmap.sampling.pca_gaussian import PCAGaussianSampler  # noqa: F401
from rigmap.sampling.uniform import UniformSampler  # noqa: F401
from rigmap.sampling.univariate_gaussian import UnivariateGaussianSampler  # noqa: F401


def _builtin() -> dict[str, type[Sampler]]:
    paper = [cls for cls in sampler_classes() if cls.paper_row is not None]
    return {cls.name: cls for cls in sorted(paper, key=lambda cls: cls.paper_row)}


#: the paper's strategies by name, in the order of its Table 2 (derived from the classes)
SAMPLERS: dict[str, type[Sampler]] = _builtin()


def available() -> list[str]:
    """Strategy names in the order of the paper's Table 2."""
    return list(SAMPLERS)


def instantiate_sampler(config: Mapping[str, Any], **overrides: Any) -> Sampler:
    """The unfitted sampler a ``conf/sampler`` node describes (``_target_`` + hyper-parameters).

    ``overrides`` replace or add hyper-parameters (e.g. the rig's soft range).
    """
    from omegaconf import DictConfig, OmegaConf

    if isinstance(config, DictConfig):
        config = OmegaConf.to_container(config, resolve=True)
    return instantiate_as({**dict(config), **overrides}, Sampler, "sampler", SamplerInputError)


def sampler_name(config: Mapping[str, Any]) -> str:
    """The name of the sampler a config node builds, read from its class (nothing is built)."""
    import hydra.utils

    target = config.get("_target_") if isinstance(config, Mapping) else None
    if target is None:
        raise SamplerInputError("sampler config: no _target_ (the sampler class)")
    cls = hydra.utils.get_class(str(target))
    if not (isinstance(cls, type) and issubclass(cls, Sampler)):
        raise SamplerInputError(f"sampler config: _target_ {target!r} is not a Sampler class")
    return cls.name


def make_sampler(name: str | None = None, **hyper_parameters: Any) -> Sampler:
    """An unfitted sampler of strategy ``name``, or of the config node given as keywords.

    ``make_sampler("gmm", n_components=3)`` looks the class up by its name;
    ``make_sampler(**cfg.sampler)`` instantiates the node's ``_target_`` (with
    ``name``, if given, checked against the class's name).
    """
    if "_target_" in hyper_parameters:
        sampler = instantiate_sampler(hyper_parameters)
        if name is not None and sampler.name != name:
            raise ValueError(
                f"sampler config {name!r}: _target_ {hyper_parameters['_target_']!r} is the "
                f"{sampler.name!r} sampler"
            )
        return sampler
    classes = {cls.name: cls for cls in sampler_classes()}
    if name not in classes:
        raise KeyError(f"unknown sampler {name!r}; available samplers: {', '.join(classes)}")
    cls = classes[name]
    try:
        return cls(**hyper_parameters)
    except TypeError as error:
        raise TypeError(f"sampler {name!r} ({cls.__name__}): {error}") from None
