"""The GPR's kernels under the name configs and model files use (``_target_:
rigmap.regression.kernels.MultiquadricKernel``); they are defined once, in
:mod:`rigmap.gp.kernels`, with the other GP kernels."""

from rigmap.gp.distances import inner_products, squared_distances
from rigmap.gp.kernels import (
    DEFAULT_SEARCH_RANGE,
    DotProductKernel,
    GaussianKernel,
    GramColumns,
    Kernel,
    LengthScaleKernel,
    LinearKernel,
    MultiquadricKernel,
    PolynomialKernel,
    ScaleKernel,
    SumKernel,
    kernel_classes,
    kernel_from_dict,
)

__all__ = [
    "DEFAULT_SEARCH_RANGE",
    "DotProductKernel",
    "GaussianKernel",
    "GramColumns",
    "Kernel",
    "LengthScaleKernel",
    "LinearKernel",
    "MultiquadricKernel",
    "PolynomialKernel",
    "ScaleKernel",
    "SumKernel",
    "inner_products",
    "kernel_classes",
    "kernel_from_dict",
    "squared_distances",
]
