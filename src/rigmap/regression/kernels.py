"""Covariance functions for the GPR inverse mapping (paper §4.1, §7.1).

Each kernel is a small immutable object holding its hyper-parameters, in the
spirit of GPyTorch's kernel modules but on numpy. Every kernel has a
``length_scale`` because the GPR's line search (§4.1.1) varies exactly that one
scalar, whatever the kernel.

A kernel is split in two steps so the line search can reuse work: ``statistic``
computes what does not depend on the hyper-parameters (squared distances for
stationary kernels, inner products for dot-product kernels) and
``from_statistic`` turns it into the Gram matrix. ``kernel(A, B)`` does both.
"""

from __future__ import annotations

import dataclasses
import math
from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np


class Kernel(ABC):
    """``k(x, x')`` on rows of ``(N, D)`` arrays; subclasses are frozen dataclasses."""

    name: ClassVar[str]
    # where the GPR's length-scale search looks unless told otherwise (six decades)
    search_range: ClassVar[tuple[float, float]]
    # what ``statistic`` computes: "squared_distance" or "inner_product"
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

    def with_length_scale(self, length_scale: float) -> Kernel:
        """A copy with another length scale (the kernel itself is immutable)."""
        return dataclasses.replace(self, length_scale=float(length_scale))  # type: ignore[type-var]

    def to_dict(self) -> dict[str, Any]:
        """Plain data for a JSON model file; ``kernel_from_dict`` reverses it."""
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # type: ignore[arg-type]
        return {"name": self.name, **fields}

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


def squared_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``||a - b||^2`` for all row pairs via the norm expansion (one matrix product).

    The expansion ``|a|^2 + |b|^2 - 2 a.b`` loses digits when the rows sit far
    from the origin, so both sets are first shifted by the mean of ``B``
    (distances do not change). What round-off remains can make near-identical
    rows slightly negative; those are clipped to zero so square roots stay
    real, and a set's distances to itself have an exact zero diagonal.
    """
    same = A is B
    A = np.asarray(A, dtype=np.float64)
    B = A if same else np.asarray(B, dtype=np.float64)
    centre = B.mean(axis=0)
    A = A - centre
    B = A if same else B - centre
    D2 = A @ B.T
    D2 *= -2.0
    D2 += np.einsum("ij,ij->i", A, A)[:, None]
    D2 += np.einsum("ij,ij->i", B, B)[None, :]
    np.maximum(D2, 0.0, out=D2)
    if same:
        np.fill_diagonal(D2, 0.0)
    return D2


def inner_products(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    return np.asarray(A, dtype=np.float64) @ np.asarray(B, dtype=np.float64).T


@dataclasses.dataclass(frozen=True)
class MultiquadricKernel(Kernel):
    """Eq. 1: ``sqrt(||x - x'||^2 + theta0^2)`` with ``theta0 = length_scale``.

    It grows with distance, so far from the data the GPR behaves like a
    piecewise-linear interpolant instead of decaying to the mean (§7.1). Its
    Gram matrix is conditionally positive definite only: solve it with LU or
    least squares, never Cholesky.
    """

    length_scale: float = 1.0
    name: ClassVar[str] = "multiquadric"
    search_range: ClassVar[tuple[float, float]] = (1e-4, 1e2)  # the paper's range (§4.1.1)
    statistic_kind: ClassVar[str] = "squared_distance"

    def __post_init__(self) -> None:
        self._set_number("length_scale", positive=True)

    def statistic(self, A, B):
        return squared_distances(A, B)

    def from_statistic(self, S):
        return np.sqrt(S + self.length_scale**2)

    def diag(self, A):
        return np.full(len(A), float(self.length_scale))


@dataclasses.dataclass(frozen=True)
class GaussianKernel(Kernel):
    """Squared exponential ``exp(-||x - x'||^2 / (2 l^2))``; decays to the mean far away."""

    length_scale: float = 1.0
    name: ClassVar[str] = "gaussian"
    # the paper's multiquadric range left its CV error still falling at 1e2 on every rig
    search_range: ClassVar[tuple[float, float]] = (1e-2, 1e4)
    statistic_kind: ClassVar[str] = "squared_distance"

    def __post_init__(self) -> None:
        self._set_number("length_scale", positive=True)

    def statistic(self, A, B):
        return squared_distances(A, B)

    def from_statistic(self, S):
        return np.exp(S * (-0.5 / self.length_scale**2))

    def diag(self, A):
        return np.ones(len(A))


@dataclasses.dataclass(frozen=True)
class LinearKernel(Kernel):
    """``x.x' / l^2 + offset``: Bayesian linear regression (affine with ``offset > 0``).

    The length scale divides the inputs; against the fixed regularisation
    ``theta1`` it sets how strongly the weights are shrunk.
    """

    length_scale: float = 1.0
    offset: float = 1.0
    name: ClassVar[str] = "linear"
    # the paper's multiquadric range left its CV error still falling at 1e2 on every rig
    search_range: ClassVar[tuple[float, float]] = (1e-2, 1e4)
    statistic_kind: ClassVar[str] = "inner_product"

    def __post_init__(self) -> None:
        self._set_number("length_scale", positive=True)
        self._set_number("offset", positive=False)

    def statistic(self, A, B):
        return inner_products(A, B)

    def from_statistic(self, S):
        return S / self.length_scale**2 + self.offset

    def diag(self, A):
        A = np.asarray(A, dtype=np.float64)
        return np.einsum("ij,ij->i", A, A) / self.length_scale**2 + self.offset


@dataclasses.dataclass(frozen=True)
class PolynomialKernel(Kernel):
    """``(x.x' / l^2 + offset)^degree``."""

    length_scale: float = 1.0
    degree: int = 2
    offset: float = 1.0
    name: ClassVar[str] = "polynomial"
    # the paper's multiquadric range left its CV error still falling at 1e2 on every rig
    search_range: ClassVar[tuple[float, float]] = (1e-2, 1e4)
    statistic_kind: ClassVar[str] = "inner_product"

    def __post_init__(self) -> None:
        self._set_number("length_scale", positive=True)
        self._set_number("offset", positive=False)
        degree = self.degree
        if isinstance(degree, bool) or int(degree) != degree or degree < 1:
            raise ValueError(f"PolynomialKernel: degree must be an integer >= 1, got {degree!r}")
        object.__setattr__(self, "degree", int(degree))

    def statistic(self, A, B):
        return inner_products(A, B)

    def from_statistic(self, S):
        return (S / self.length_scale**2 + self.offset) ** self.degree

    def diag(self, A):
        A = np.asarray(A, dtype=np.float64)
        return (np.einsum("ij,ij->i", A, A) / self.length_scale**2 + self.offset) ** self.degree


class GramColumns:
    """Columns ``k(A, a_i)`` of the Gram matrix of ``A``, one at a time.

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


KERNELS: dict[str, type[Kernel]] = {
    cls.name: cls for cls in (MultiquadricKernel, GaussianKernel, LinearKernel, PolynomialKernel)
}


def make_kernel(name: str, **params: Any) -> Kernel:
    """A kernel by its name (``multiquadric``, ``gaussian``, ``linear``, ``polynomial``)."""
    try:
        cls = KERNELS[name]
    except KeyError:
        raise ValueError(f"unknown kernel {name!r}; available kernels: {sorted(KERNELS)}") from None
    try:
        return cls(**params)
    except TypeError as error:
        allowed = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        raise ValueError(
            f"kernel {name!r}: bad parameters {sorted(params)}; it takes {allowed}"
        ) from error


def kernel_from_dict(data: dict[str, Any]) -> Kernel:
    """Inverse of ``Kernel.to_dict``."""
    data = dict(data)
    if "name" not in data:
        raise ValueError(f"kernel description has no 'name' field: keys {sorted(data)}")
    return make_kernel(data.pop("name"), **data)
