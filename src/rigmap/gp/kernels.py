"""Covariance functions of rigmap's GPs, each defined once.

- :func:`rbf` — the squared exponential with a variance, ``σ² exp(−‖x − x'‖² / 2l²)``,
  on numpy arrays or torch tensors from one expression: the edits' shared-kernel GP
  (:mod:`rigmap.edits.gp`, plus noise), the GPLVM (:mod:`rigmap.latent.gplvm`, torch,
  differentiated by autograd; plus white noise) and its dynamics prior, and the
  particle's numpy copy of the GPLVM's field (:mod:`rigmap.latent.particle`).
  :func:`rbf_input_gradient` and :func:`rbf_d_log_lengthscale` are its derivatives.
- The kernel objects of the GPR inverse mapping (paper §4.1, §7.1), below.

Each kernel object is a small immutable object holding its hyper-parameters, in the
spirit of GPyTorch's kernel modules but on numpy. Every kernel has a
``length_scale`` because the GPR's line search (§4.1.1) varies exactly that one
scalar, whatever the kernel; :class:`LengthScaleKernel` holds it, checks it and
says where the search looks. Kernels compose as GPyTorch's do: ``k1 + k2`` is a
:class:`SumKernel` (Gram matrices added) and ``c * k`` a :class:`ScaleKernel`
(Gram matrix times ``c``). Configs and model files name them by their old home,
``rigmap.regression.kernels``, which re-exports them.

A kernel object is split in two steps so the line search can reuse work: ``statistic``
computes what does not depend on the hyper-parameters (squared distances for
stationary kernels, inner products for dot-product kernels, one of each per
part for a sum) and ``from_statistic`` turns it into the Gram matrix.
``kernel(A, B)`` does both.

:class:`GaussianKernel` is the same function as :func:`rbf` with ``σ² = 1``, but
evaluates its exponent as ``S · (−½ / l²)`` (one multiplication per entry), where
:func:`rbf` divides, ``(−½ S) / l²``: the two round differently in the last bit, and
each is what its pipeline's committed numbers were computed with, so neither is
rewritten as the other.
"""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from rigmap.gp.distances import expanded_squared_distances, inner_products, squared_distances

# Where the line search looks unless the kernel or the GPR says otherwise: six decades.
# Ours: the paper's multiquadric range (1e-4..1e2) left the CV error of these kernels
# still falling at 1e2 on every rig.
DEFAULT_SEARCH_RANGE = (1e-2, 1e4)


def _is_torch(x) -> bool:
    return type(x).__module__.startswith("torch")


def rbf(sq, variance, lengthscale2):
    """``variance · exp(−sq / 2 l²)`` from squared distances (numpy or torch; torch keeps
    the autograd graph), ``lengthscale2 = l²``."""
    scaled = -0.5 * sq / lengthscale2
    return variance * (scaled.exp() if _is_torch(scaled) else np.exp(scaled))


def rbf_gram(A, B, variance, lengthscale2):
    """:func:`rbf` between every row of ``A`` and of ``B`` (plain norm-expansion distances,
    :func:`~rigmap.gp.distances.expanded_squared_distances`)."""
    return rbf(expanded_squared_distances(A, B), variance, lengthscale2)


def rbf_input_gradient(K, differences, lengthscale2):
    """``∂k(x, x_i)/∂x = −k_i (x − x_i) / l²`` for a cross Gram matrix ``K`` ``(M, N)`` and
    ``differences`` ``x − x_i`` ``(M, N, q)``: ``(M, N, q)``."""
    return -(K[..., None] * differences) / lengthscale2


def rbf_d_log_lengthscale(K, sq, lengthscale2):
    """``∂K/∂log l = K ∘ sq / l²`` (``K`` an RBF Gram matrix, ``sq`` its squared distances);
    ``∂K/∂log σ = 2K``."""
    return K * sq / lengthscale2


class Kernel(ABC):
    """``k(x, x')`` on rows of ``(N, D)`` arrays; subclasses are frozen dataclasses."""

    name: ClassVar[str]
    #: the label reports print (rigmap.catalog); ``None``: the name
    title: ClassVar[str | None] = None
    #: a kernel the paper does not compare (the report marks its row)
    extra: ClassVar[bool] = False
    # where the GPR's length-scale search looks unless told otherwise
    search_range: ClassVar[tuple[float, float]] = DEFAULT_SEARCH_RANGE
    # what ``statistic`` computes: "squared_distance", "inner_product" or "stacked" (sums)
    statistic_kind: ClassVar[str]
    length_scale: float

    def __call__(self, A: np.ndarray, B: np.ndarray | None = None) -> np.ndarray:
        """Gram matrix ``(len(A), len(B))``; ``B`` defaults to ``A``."""
        return self.from_statistic(self.statistic(A, A if B is None else B))

    @abstractmethod
    def statistic(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """The hyper-parameter-free pairwise quantity the kernel is a function of."""

    @abstractmethod
    def from_statistic(self, S: np.ndarray) -> np.ndarray:
        """Gram matrix from ``statistic(A, B)``; leaves ``S`` unchanged (it is reused)."""

    @abstractmethod
    def diag(self, A: np.ndarray) -> np.ndarray:
        """``k(x, x)`` for every row, without forming the Gram matrix."""

    @property
    def label(self) -> str:
        """The kernel part of a model id: the name, or how a composite is built."""
        return self.name

    def columns(self, A: np.ndarray) -> Callable[[int], np.ndarray]:
        """``i -> k(A, a_i)``, one Gram column at a time (for greedy subsampling)."""
        return GramColumns(self, A)

    def with_length_scale(self, length_scale: float) -> Kernel:
        """A copy with another length scale (the kernel itself is immutable)."""
        return dataclasses.replace(self, length_scale=float(length_scale))  # type: ignore[type-var]

    def to_dict(self) -> dict[str, Any]:
        """Plain data for a JSON model file; ``kernel_from_dict`` reverses it."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # type: ignore[arg-type]
        return {"name": self.name, **fields}

    def __add__(self, other: Kernel) -> SumKernel:
        if not isinstance(other, Kernel):
            return NotImplemented
        parts = [*_summands(self), *_summands(other)]
        return SumKernel(tuple(parts))

    def __mul__(self, scale: float) -> ScaleKernel:
        if isinstance(scale, Kernel) or isinstance(scale, bool):
            return NotImplemented
        return ScaleKernel(self, scale)

    __rmul__ = __mul__

    def _set_number(self, field: str, *, positive: bool) -> None:
        """Coerce a hyper-parameter to a plain float (numpy / YAML ints) and check its range."""
        value = getattr(self, field)
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if (
            isinstance(value, bool)
            or not math.isfinite(number)
            or number < 0
            or (positive and number == 0)
        ):
            wanted = "a positive number" if positive else "a number >= 0"
            raise ValueError(f"{type(self).__name__}: {field} must be {wanted}, got {value!r}")
        object.__setattr__(self, field, number)


def _summands(kernel: Kernel) -> tuple[Kernel, ...]:
    return kernel.kernels if isinstance(kernel, SumKernel) else (kernel,)


@dataclasses.dataclass(frozen=True)
class LengthScaleKernel(Kernel):
    """A kernel of one length scale (and perhaps more hyper-parameters after it)."""

    length_scale: float = 1.0

    def __post_init__(self) -> None:
        self._set_number("length_scale", positive=True)


@dataclasses.dataclass(frozen=True)
class MultiquadricKernel(LengthScaleKernel):
    """Eq. 1: ``sqrt(||x - x'||^2 + theta0^2)`` with ``theta0 = length_scale``.

    It grows with distance, so far from the data the GPR behaves like a
    piecewise-linear interpolant instead of decaying to the mean (§7.1). Its
    Gram matrix is conditionally positive definite only: solve it with LU or
    least squares, never Cholesky.
    """

    name: ClassVar[str] = "multiquadric"
    title: ClassVar[str | None] = "Multiquadric"  # §7.1's label
    search_range: ClassVar[tuple[float, float]] = (1e-4, 1e2)  # the paper's range (§4.1.1)
    statistic_kind: ClassVar[str] = "squared_distance"

    def statistic(self, A, B):
        return squared_distances(A, B)

    def from_statistic(self, S):
        return np.sqrt(S + self.length_scale**2)

    def diag(self, A):
        return np.full(len(A), float(self.length_scale))


@dataclasses.dataclass(frozen=True)
class GaussianKernel(LengthScaleKernel):
    """Squared exponential ``exp(-||x - x'||^2 / (2 l^2))``; decays to the mean far away."""

    name: ClassVar[str] = "gaussian"
    title: ClassVar[str | None] = "Gaussian"  # §7.1's label
    statistic_kind: ClassVar[str] = "squared_distance"

    def statistic(self, A, B):
        return squared_distances(A, B)

    def from_statistic(self, S):
        return np.exp(S * (-0.5 / self.length_scale**2))

    def diag(self, A):
        return np.ones(len(A))


@dataclasses.dataclass(frozen=True)
class DotProductKernel(LengthScaleKernel):
    """``(x.x' / l^2 + offset)^degree``; the linear kernel is degree 1.

    The length scale divides the inputs; against the fixed regularisation
    ``theta1`` it sets how strongly the weights are shrunk.
    """

    offset: float = 1.0
    statistic_kind: ClassVar[str] = "inner_product"
    degree: ClassVar[int] = 1

    def __post_init__(self) -> None:
        super().__post_init__()
        self._set_number("offset", positive=False)

    def statistic(self, A, B):
        return inner_products(A, B)

    def from_statistic(self, S):
        return self._power(S / self.length_scale**2 + self.offset)

    def diag(self, A):
        A = np.asarray(A, dtype=np.float64)
        return self._power(np.einsum("ij,ij->i", A, A) / self.length_scale**2 + self.offset)

    def _power(self, base: np.ndarray) -> np.ndarray:
        return base if self.degree == 1 else base**self.degree


@dataclasses.dataclass(frozen=True)
class LinearKernel(DotProductKernel):
    """``x.x' / l^2 + offset``: Bayesian linear regression (affine with ``offset > 0``)."""

    name: ClassVar[str] = "linear"
    title: ClassVar[str | None] = "Linear"  # §7.1's label


@dataclasses.dataclass(frozen=True)
class PolynomialKernel(DotProductKernel):
    """``(x.x' / l^2 + offset)^degree``."""

    degree: int = 2  # type: ignore[assignment]  # a field here, fixed at 1 for the linear kernel
    name: ClassVar[str] = "polynomial"
    title: ClassVar[str | None] = "Polynomial"  # §7.1's label

    def __post_init__(self) -> None:
        super().__post_init__()
        degree = self.degree
        if isinstance(degree, bool) or int(degree) != degree or degree < 1:
            raise ValueError(f"PolynomialKernel: degree must be an integer >= 1, got {degree!r}")
        object.__setattr__(self, "degree", int(degree))


@dataclasses.dataclass(frozen=True)
class SumKernel(Kernel):
    """``k1 + k2 + …``: the Gram matrices of the parts added (GPyTorch's ``AdditiveKernel``).

    The line search varies one scalar (§4.1.1), so the parts share it:
    ``with_length_scale`` gives every part the same length scale, and
    ``length_scale`` is the first part's. The search range spans the parts'.
    """

    kernels: tuple[Kernel, ...] = ()
    name: ClassVar[str] = "sum"
    statistic_kind: ClassVar[str] = "stacked"

    def __post_init__(self) -> None:
        parts = tuple(_as_kernel(k, "SumKernel: kernels") for k in self.kernels)
        if len(parts) < 2:
            raise ValueError(f"SumKernel: needs at least two kernels, got {len(parts)}")
        object.__setattr__(self, "kernels", parts)

    @property
    def length_scale(self) -> float:  # type: ignore[override]
        return self.kernels[0].length_scale

    @property
    def search_range(self) -> tuple[float, float]:  # type: ignore[override]
        return (
            min(k.search_range[0] for k in self.kernels),
            max(k.search_range[1] for k in self.kernels),
        )

    def statistic(self, A, B):
        """Each part's statistic, stacked on a last axis (rows and columns index as usual)."""
        return np.stack([k.statistic(A, B) for k in self.kernels], axis=-1)

    def from_statistic(self, S):
        total = self.kernels[0].from_statistic(S[..., 0])
        for i, kernel in enumerate(self.kernels[1:], start=1):
            total = total + kernel.from_statistic(S[..., i])
        return total

    def diag(self, A):
        return sum(k.diag(A) for k in self.kernels)

    def columns(self, A):
        parts = [k.columns(A) for k in self.kernels]
        return lambda i: sum(part(i) for part in parts)

    @property
    def label(self) -> str:
        return "_plus_".join(k.label for k in self.kernels)

    def with_length_scale(self, length_scale: float) -> SumKernel:
        return SumKernel(tuple(k.with_length_scale(length_scale) for k in self.kernels))

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "kernels": [k.to_dict() for k in self.kernels]}


@dataclasses.dataclass(frozen=True)
class ScaleKernel(Kernel):
    """``outputscale * k``: the base kernel's Gram matrix scaled (GPyTorch's ``ScaleKernel``)."""

    base_kernel: Kernel = dataclasses.field(default_factory=lambda: MultiquadricKernel())
    outputscale: float = 1.0
    name: ClassVar[str] = "scale"

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "base_kernel", _as_kernel(self.base_kernel, "ScaleKernel: base_kernel")
        )
        self._set_number("outputscale", positive=True)

    @property
    def length_scale(self) -> float:  # type: ignore[override]
        return self.base_kernel.length_scale

    @property
    def search_range(self) -> tuple[float, float]:  # type: ignore[override]
        return self.base_kernel.search_range

    @property
    def statistic_kind(self) -> str:  # type: ignore[override]
        return self.base_kernel.statistic_kind

    def statistic(self, A, B):
        return self.base_kernel.statistic(A, B)

    def from_statistic(self, S):
        return self.outputscale * self.base_kernel.from_statistic(S)

    def diag(self, A):
        return self.outputscale * self.base_kernel.diag(A)

    def columns(self, A):
        base = self.base_kernel.columns(A)
        return lambda i: self.outputscale * base(i)

    @property
    def label(self) -> str:
        return f"scaled_{self.base_kernel.label}"

    def with_length_scale(self, length_scale: float) -> ScaleKernel:
        return ScaleKernel(self.base_kernel.with_length_scale(length_scale), self.outputscale)

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "base_kernel": self.base_kernel.to_dict(),
            "outputscale": self.outputscale,
        }


def _as_kernel(value: Any, where: str) -> Kernel:
    """A kernel, or a ``to_dict`` mapping of one (as a kernel file or a plain config holds)."""
    if isinstance(value, Kernel):
        return value
    if isinstance(value, dict):
        return kernel_from_dict(value)
    raise ValueError(f"{where}: expected a kernel, got {type(value).__name__}")


class GramColumns:
    """Columns ``k(A, a_i)`` of the Gram matrix of ``A``, one at a time (one-part kernels).

    Greedy algorithms need one column per step; this centres ``A`` and takes
    its row norms once instead of at every call, which makes a column one
    matrix-vector product.
    """

    def __init__(self, kernel: Kernel, A: np.ndarray):
        self.kernel = kernel
        self.distances = kernel.statistic_kind == "squared_distance"
        A = np.asarray(A, dtype=np.float64)
        # distances do not change under a shift, and the norm expansion is accurate when centred
        self.A = np.ascontiguousarray(A - A.mean(axis=0) if self.distances else A)
        self.sq_norms = np.einsum("ij,ij->i", self.A, self.A) if self.distances else None

    def __call__(self, i: int) -> np.ndarray:
        statistic = self.A @ self.A[i]
        if self.distances:
            statistic *= -2.0
            statistic += self.sq_norms
            statistic += self.sq_norms[i]
            np.maximum(statistic, 0.0, out=statistic)
            statistic[i] = 0.0
        return self.kernel.from_statistic(statistic)


def kernel_classes() -> dict[str, type[Kernel]]:
    """Every kernel class by its ``name`` (the built-in ones and any other imported subclass)."""
    found: dict[str, type[Kernel]] = {}
    pending = list(Kernel.__subclasses__())
    while pending:
        cls = pending.pop(0)
        pending += cls.__subclasses__()
        if isinstance(cls.__dict__.get("name"), str):
            found.setdefault(cls.name, cls)
    return found


def kernel_from_dict(data: dict[str, Any]) -> Kernel:
    """Inverse of ``Kernel.to_dict`` (a kernel saved in a model file; no code is imported)."""
    data = dict(data)
    if "name" not in data:
        raise ValueError(f"kernel description has no 'name' field: keys {sorted(data)}")
    name = data.pop("name")
    classes = kernel_classes()
    if name not in classes:
        raise ValueError(f"unknown kernel {name!r}; available kernels: {sorted(classes)}")
    cls = classes[name]
    if cls is SumKernel:
        parts = data.get("kernels", ())
        data["kernels"] = tuple(_as_kernel(k, "SumKernel: kernels") for k in parts)
    try:
        return cls(**data)
    except TypeError as error:
        allowed = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        raise ValueError(
            f"kernel {name!r}: bad parameters {sorted(data)}; it takes {allowed}"
        ) from error
