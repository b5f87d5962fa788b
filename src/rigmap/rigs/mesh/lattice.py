"""Free-form deformation by a trivariate Bernstein lattice (Sederberg & Parry).

A point's position is a fixed blend of the lattice's control points, the
weights being products of Bernstein polynomials of its coordinates inside the
lattice box. The weights depend only on the rest position, so they are
computed once; deforming is one matrix product with the moved control points,
batched and differentiable. Control points are moved by the whole-body
deformers of :mod:`rigmap.rigs.mesh.lattice_deformers`. Bernstein bases
reproduce affine maps, so an untouched lattice is exactly the identity.
"""

from __future__ import annotations

from math import comb

import numpy as np
import torch


class BernsteinLattice:
    """A box ``[lower, upper]`` (cm) with ``(l+1)(m+1)(n+1)`` control points for ``degrees``."""

    def __init__(self, lower, upper, degrees=(2, 5, 2)):
        self.lower = np.asarray(lower, dtype=np.float64)
        self.upper = np.asarray(upper, dtype=np.float64)
        self.degrees = tuple(int(d) for d in degrees)
        if self.lower.shape != (3,) or self.upper.shape != (3,):
            raise ValueError(f"lattice box corners must be 3-vectors, got {lower!r}, {upper!r}")
        if np.any(self.upper <= self.lower):
            raise ValueError(f"lattice box is empty: lower {self.lower}, upper {self.upper}")
        if len(self.degrees) != 3 or min(self.degrees) < 1:
            raise ValueError(f"lattice degrees must be three integers >= 1, got {degrees!r}")
        self.size = self.upper - self.lower
        grids = np.meshgrid(*(np.linspace(0, 1, d + 1) for d in self.degrees), indexing="ij")
        unit = np.stack([g.reshape(-1) for g in grids], axis=1)
        self.rest_control_points = self.lower + unit * self.size  # (K, 3), last axis fastest

    @property
    def n_control_points(self) -> int:
        return len(self.rest_control_points)

    def local_coordinates(self, points) -> np.ndarray:
        """Points in box units: 0 at ``lower``, 1 at ``upper`` (outside the box extrapolates)."""
        return (np.asarray(points, dtype=np.float64) - self.lower) / self.size

    def weights(self, points) -> np.ndarray:
        """``(P, K)`` blend weights: deformed point = weights @ control points."""
        s = self.local_coordinates(points)
        bases = [_bernstein(s[:, a], self.degrees[a]) for a in range(3)]
        return _tensor_product(*bases)

    def jacobian_weights(self, points) -> np.ndarray:
        """``(P, 3, K)``: d(deformed point)/d(rest coordinate a) is ``[:, a] @ control points``."""
        s = self.local_coordinates(points)
        values = [_bernstein(s[:, a], self.degrees[a]) for a in range(3)]
        slopes = [_bernstein_slope(s[:, a], self.degrees[a]) / self.size[a] for a in range(3)]
        rows = []
        for a in range(3):
            factors = [slopes[b] if b == a else values[b] for b in range(3)]
            rows.append(_tensor_product(*factors))
        return np.stack(rows, axis=1)


def deform(weights: torch.Tensor, control_points: torch.Tensor) -> torch.Tensor:
    """``(P, K)`` weights and ``(N, K, 3)`` control points -> ``(N, P, 3)`` points."""
    return blend_rows(weights, control_points)


def blend_rows(weights: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
    """``(P, K)`` weights times per-pose rows ``(N, K, D)`` -> ``(N, P, D)``, as one matrix product.

    One ``(P, K) @ (K, N*D)`` GEMM is much faster than N small products.
    """
    n, k, d = rows.shape
    flat = rows.permute(1, 0, 2).reshape(k, n * d)
    return torch.matmul(weights, flat).reshape(-1, n, d).permute(1, 0, 2)


def _bernstein(s: np.ndarray, degree: int) -> np.ndarray:
    """``(P, degree+1)`` Bernstein basis values."""
    i = np.arange(degree + 1)
    coefficients = np.array([comb(degree, k) for k in i], dtype=np.float64)
    return coefficients * s[:, None] ** i * (1 - s[:, None]) ** (degree - i)


def _bernstein_slope(s: np.ndarray, degree: int) -> np.ndarray:
    """``(P, degree+1)`` derivatives of the Bernstein basis in ``s``."""
    lower = _bernstein(s, degree - 1)
    padded = np.pad(lower, ((0, 0), (1, 1)))
    return degree * (padded[:, :-1] - padded[:, 1:])


def _tensor_product(bx: np.ndarray, by: np.ndarray, bz: np.ndarray) -> np.ndarray:
    return np.einsum("pi,pj,pk->pijk", bx, by, bz).reshape(len(bx), -1)
