"""Batched rigid-transform maths in torch: Euler angles, blends, aim frames.

Everything works on a leading batch dimension ``N`` and stays differentiable.
Rotation matrices act on column vectors; Euler order ``"xyz"`` means rotate
about x first, then y, then z (Maya's convention): ``R = Rz @ Ry @ Rx``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

ROTATION_ORDERS = ("xyz", "yzx", "zxy", "xzy", "yxz", "zyx")
_EPS = 1e-9


def axis_rotation(angle: torch.Tensor, axis: str) -> torch.Tensor:
    """``(N,)`` angles about a principal axis -> ``(N, 3, 3)``."""
    c, s = torch.cos(angle), torch.sin(angle)
    one, zero = torch.ones_like(angle), torch.zeros_like(angle)
    if axis == "x":
        rows = [one, zero, zero, zero, c, -s, zero, s, c]
    elif axis == "y":
        rows = [c, zero, s, zero, one, zero, -s, zero, c]
    elif axis == "z":
        rows = [c, -s, zero, s, c, zero, zero, zero, one]
    else:
        raise ValueError(f"axis must be x, y or z, got {axis!r}")
    return torch.stack(rows, dim=-1).reshape(*angle.shape, 3, 3)


def euler_matrix(angles: torch.Tensor, order: str = "xyz") -> torch.Tensor:
    """``(N, 3)`` Euler angles (x, y, z in radians) -> ``(N, 3, 3)`` in ``order``."""
    if order not in ROTATION_ORDERS:
        raise ValueError(f"rotation order must be one of {ROTATION_ORDERS}, got {order!r}")
    by_axis = {"x": angles[..., 0], "y": angles[..., 1], "z": angles[..., 2]}
    R = axis_rotation(by_axis[order[0]], order[0])
    for axis in order[1:]:
        R = axis_rotation(by_axis[axis], axis) @ R
    return R


def axis_angle_matrix(axis: torch.Tensor, angle: torch.Tensor) -> torch.Tensor:
    """Rodrigues: unit ``(N, 3)`` axes and ``(N,)`` angles -> ``(N, 3, 3)``."""
    x, y, z = axis.unbind(-1)
    zero = torch.zeros_like(x)
    K = torch.stack([zero, -z, y, z, zero, -x, -y, x, zero], dim=-1).reshape(*x.shape, 3, 3)
    s = torch.sin(angle)[..., None, None]
    c = torch.cos(angle)[..., None, None]
    eye = torch.eye(3, dtype=axis.dtype).expand_as(K)
    return eye + s * K + (1 - c) * (K @ K)


def normalize(v: torch.Tensor) -> torch.Tensor:
    return v / torch.sqrt((v * v).sum(-1, keepdim=True) + _EPS * _EPS)


def orthonormalize(M: torch.Tensor) -> torch.Tensor:
    """Nearest-ish rotation to ``M`` by Gram-Schmidt on its first two columns."""
    x = normalize(M[..., :, 0])
    y = M[..., :, 1]
    y = normalize(y - (y * x).sum(-1, keepdim=True) * x)
    z = torch.linalg.cross(x, y, dim=-1)
    return torch.stack([x, y, z], dim=-1)


def blend_rotations(Ra: torch.Tensor, Rb: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """Blend two rotation fields by ``(N,)`` weight in [0, 1]; exact at 0 and 1.

    Matrix lerp then Gram-Schmidt: what a two-target orient constraint does,
    smooth and differentiable everywhere the rotations are less than 180° apart.
    """
    w = weight[..., None, None]
    return orthonormalize((1 - w) * Ra + w * Rb)


def frame_from_axes(forward: torch.Tensor, up: torch.Tensor) -> torch.Tensor:
    """Right-handed frame with columns (right, up', forward): z along ``forward``."""
    z = normalize(forward)
    x = normalize(torch.linalg.cross(up, z, dim=-1))
    y = torch.linalg.cross(z, x, dim=-1)
    return torch.stack([x, y, z], dim=-1)


def rotation_between(rest_dir, rest_normal, new_dir, new_normal) -> torch.Tensor:
    """Rotation taking the rest (direction, normal) pair onto the new pair."""
    F0 = frame_from_axes(rest_dir, rest_normal)
    F1 = frame_from_axes(new_dir, new_normal)
    return F1 @ F0.transpose(-1, -2)


@dataclass
class Transform:
    """An affine transform per batch item: ``p -> R @ p + t``.

    ``R`` is ``(N, 3, 3)`` (a rotation, possibly times a scale), ``t`` is ``(N, 3)``.
    """

    R: torch.Tensor
    t: torch.Tensor

    def compose(self, local: Transform) -> Transform:
        """``self ∘ local``: ``local`` expressed in this transform's space."""
        return Transform(self.R @ local.R, (self.R @ local.t[..., None])[..., 0] + self.t)

    def apply(self, p: torch.Tensor) -> torch.Tensor:
        """Map ``(N, 3)`` or ``(3,)`` points."""
        if p.ndim == 1:
            p = p.expand_as(self.t)
        return (self.R @ p[..., None])[..., 0] + self.t

    def rotate(self, v: torch.Tensor) -> torch.Tensor:
        if v.ndim == 1:
            v = v.expand_as(self.t)
        return (self.R @ v[..., None])[..., 0]

    @staticmethod
    def identity(n: int, dtype: torch.dtype) -> Transform:
        return Transform(torch.eye(3, dtype=dtype).expand(n, 3, 3), torch.zeros(n, 3, dtype=dtype))

    @staticmethod
    def pivot(R: torch.Tensor, pivot: torch.Tensor) -> Transform:
        """Rotation ``R`` about the point ``pivot``: ``T(p) R T(-p)``."""
        if pivot.ndim == 1:
            pivot = pivot.expand(R.shape[0], 3)
        return Transform(R, pivot - (R @ pivot[..., None])[..., 0])
