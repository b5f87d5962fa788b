"""The built-in samplers by name.

A sampler is built like every other part: the application layer
(:mod:`rigmap.app.objects`) instantiates its ``conf/sampler/*.yaml`` node, whose
``_target_`` is the class; the class knows its own ``name``, so the yaml does not
restate it. A new strategy is one class plus one yaml file.

``make_sampler``, ``SAMPLERS`` and ``available`` are kept for callers that
choose a strategy by name (the command line, benchmarks, figures): they are
derived from the sampler classes themselves, not kept as a second list.
"""

from __future__ import annotations

from typing import Any

from rigmap.sampling.base import Sampler, sampler_classes

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


def make_sampler(name: str | None = None, **hyper_parameters: Any) -> Sampler:
    """An unfitted sampler of strategy ``name``: ``make_sampler("gmm", n_components=3)``
    looks the class up by its name (a config node's ``_target_`` is built by
    :func:`rigmap.app.objects.sampler_from_node`)."""
    if "_target_" in hyper_parameters:
        raise TypeError(
            f"make_sampler({name!r}): a config node (_target_) is built by "
            "rigmap.app.objects.sampler_from_node, not by the library"
        )
    classes = {cls.name: cls for cls in sampler_classes()}
    if name not in classes:
        raise KeyError(f"unknown sampler {name!r}; available samplers: {', '.join(classes)}")
    cls = classes[name]
    try:
        return cls(**hyper_parameters)
    except TypeError as error:
        raise TypeError(f"sampler {name!r} ({cls.__name__}): {error}") from None
