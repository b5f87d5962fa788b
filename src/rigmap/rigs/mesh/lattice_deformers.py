"""Whole-body deformers that move lattice control points: squash-stretch, twist, bend.

Each takes control points ``(N, K, 3)`` (cm, Y up) and ``(N,)`` amounts and
returns moved points, batched and differentiable. They act along the vertical
axis from a ``base`` height over a ``length`` (cm), like Maya's nonlinear
deformers bound to a lattice: points below the base do not move, points past
the end carry on rigidly. Applied to a lattice rather than to the mesh, the
result on the surface is the smooth Bernstein blend of these moves.
"""

from __future__ import annotations

import math

import torch


def squash_stretch(points: torch.Tensor, amount: torch.Tensor, *, base: float, center_xz):
    """Volume-preserving: height x ``e^amount`` above ``base``, width x ``e^(-amount/2)``."""
    height_scale = torch.exp(amount)[:, None]
    side_scale = torch.exp(-0.5 * amount)[:, None]
    cx, cz = float(center_xz[0]), float(center_xz[1])
    x = cx + (points[..., 0] - cx) * side_scale
    y = base + (points[..., 1] - base) * height_scale
    z = cz + (points[..., 2] - cz) * side_scale
    return torch.stack([x, y, z], dim=-1)


def twist(points: torch.Tensor, angle: torch.Tensor, *, base: float, length: float, center_xz):
    """Rotate about the vertical axis through ``center_xz`` by ``angle`` x (fraction of length)."""
    fraction = ((points[..., 1] - base) / length).clamp(0.0, 1.0)
    a = angle[:, None] * fraction
    c, s = torch.cos(a), torch.sin(a)
    cx, cz = float(center_xz[0]), float(center_xz[1])
    dx, dz = points[..., 0] - cx, points[..., 2] - cz
    # positive angle turns +z (forward) towards +x (the character's left)
    x = cx + c * dx + s * dz
    z = cz - s * dx + c * dz
    return torch.stack([x, points[..., 1], z], dim=-1)


def bend(
    points: torch.Tensor, angle: torch.Tensor, *, base: float, length: float, axis: str, center
):
    """Bend the column above ``base`` into a circular arc of total ``angle`` over ``length``.

    ``axis="z"`` bends towards +z (forward) for a positive angle, ``axis="x"``
    towards +x (the character's left). ``center`` is the horizontal coordinate
    of the neutral line in that axis (cm): points on it keep their arc length.
    """
    if axis not in ("x", "z"):
        raise ValueError(f"bend axis must be 'x' or 'z', got {axis!r}")
    k = 0 if axis == "x" else 2
    h = points[..., 1] - base
    on_arc = h.clamp(0.0, length)
    beyond = h - on_arc  # straight continuation past the arc (negative below base is 0 here)
    below = (h < 0).to(points.dtype)
    on_arc = on_arc * (1 - below)
    beyond = beyond * (1 - below)
    theta = angle[:, None]
    phi = theta * on_arc / length
    offset = points[..., k] - center
    # arc of curvature theta/length: sin(phi)/kappa = h sinc(phi), (1 - cos phi)/kappa
    sin_over_kappa = on_arc * _sinc(phi)
    versin_over_kappa = on_arc * 0.5 * phi * _sinc(0.5 * phi) ** 2
    c, s = torch.cos(phi), torch.sin(phi)
    ct, st = torch.cos(theta), torch.sin(theta)
    height = base + sin_over_kappa - offset * s + beyond * ct
    side = center + versin_over_kappa + offset * c + beyond * st
    # below the base nothing moves
    height = below * points[..., 1] + (1 - below) * height
    side = below * points[..., k] + (1 - below) * side
    if axis == "x":
        return torch.stack([side, height, points[..., 2]], dim=-1)
    return torch.stack([points[..., 0], height, side], dim=-1)


def _sinc(x: torch.Tensor) -> torch.Tensor:
    """sin(x)/x, 1 at 0 (torch.sinc is the normalised sin(pi x)/(pi x))."""
    return torch.sinc(x / math.pi)
