"""Supersampling: extra control vectors around the animator corpus, posed by the rig (§5.2).

Six strategies of the paper's Table 2, each a class with ``fit(Y_corpus)`` and
``sample(n, rng)``; ``supersample`` draws, clamps and poses them resumably.
"""

from rigmap.sampling.base import (
    Sampler,
    SamplerInputError,
    SamplerNotFittedError,
    sampler_classes,
)
from rigmap.sampling.clamping import ClampResult, clamp_to_limits
from rigmap.sampling.gmm import GaussianMixtureSampler
from rigmap.sampling.multivariate_gaussian import MultivariateGaussianSampler
from rigmap.sampling.none import NoExtraSamples
from rigmap.sampling.pca_gaussian import PCAGaussianSampler
from rigmap.sampling.registry import (
    SAMPLERS,
    available,
    make_sampler,
)
from rigmap.sampling.supersample import (
    SupersampleError,
    SupersampleResult,
    load_samples,
    supersample,
)
from rigmap.sampling.uniform import UniformSampler
from rigmap.sampling.univariate_gaussian import UnivariateGaussianSampler

__all__ = [
    "SAMPLERS",
    "ClampResult",
    "GaussianMixtureSampler",
    "MultivariateGaussianSampler",
    "NoExtraSamples",
    "PCAGaussianSampler",
    "Sampler",
    "SamplerInputError",
    "SamplerNotFittedError",
    "SupersampleError",
    "SupersampleResult",
    "UniformSampler",
    "UnivariateGaussianSampler",
    "available",
    "clamp_to_limits",
    "load_samples",
    "make_sampler",
    "sampler_classes",
    "supersample",
]
