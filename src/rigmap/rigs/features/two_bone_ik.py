"""Analytic two-bone IK with a pole vector (knees, elbows, hocks).

Given the chain root, the target and a pole point, the mid joint lies in the
plane spanned by root→target and root→pole, on the pole's side, at the
distances the two bone lengths allow. With stretch off the bone lengths are
kept and an out-of-reach target is approached along the root→target line;
with ``stretch`` in (0, 1] the bones lengthen (uniformly) to reach it.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from rigmap.rigs.engine.transforms import axis_angle_matrix, normalize

# How close to full extension a non-stretching limb may get (keeps the knee
# direction defined and the solution differentiable).
MAX_REACH_FRACTION = 0.9999


class TwoBoneSolution(NamedTuple):
    mid: torch.Tensor  # (N, 3) knee / elbow position
    end: torch.Tensor  # (N, 3) ankle / wrist position
    normal: torch.Tensor  # (N, 3) unit normal of the limb plane (axis × pole direction)
    lengths: tuple[torch.Tensor, torch.Tensor]  # actual (possibly stretched) bone lengths


def solve_two_bone_ik(
    root: torch.Tensor,
    target: torch.Tensor,
    pole: torch.Tensor,
    upper_length: float,
    lower_length: float,
    *,
    stretch: torch.Tensor | None = None,
    twist: torch.Tensor | None = None,
) -> TwoBoneSolution:
    """Place mid and end joints for ``(N, 3)`` root, target and pole points."""
    to_target = target - root
    distance = torch.linalg.norm(to_target, dim=-1)
    axis = to_target / distance.clamp_min(1e-9)[..., None]

    l1 = torch.full_like(distance, upper_length)
    l2 = torch.full_like(distance, lower_length)
    if stretch is not None:
        # lengthen both bones by the factor needed to reach, scaled by `stretch`
        needed = (distance / ((upper_length + lower_length) * MAX_REACH_FRACTION)).clamp_min(1.0)
        factor = 1.0 + stretch.clamp(0.0, 1.0) * (needed - 1.0)
        l1, l2 = l1 * factor, l2 * factor
    longest = (l1 + l2) * MAX_REACH_FRACTION
    shortest = (l1 - l2).abs() * 1.0001 + 1e-6
    reach = torch.minimum(torch.maximum(distance, shortest), longest)

    # distance along the axis to the mid joint's foot point, then height off the axis
    along = (l1 * l1 - l2 * l2 + reach * reach) / (2 * reach)
    height = torch.sqrt((l1 * l1 - along * along).clamp_min(1e-12))

    to_pole = pole - root
    side = normalize(to_pole - (to_pole * axis).sum(-1, keepdim=True) * axis)
    if twist is not None:
        side = (axis_angle_matrix(axis, twist) @ side[..., None])[..., 0]
    normal = normalize(torch.linalg.cross(axis, side, dim=-1))

    mid = root + along[..., None] * axis + height[..., None] * side
    end = root + reach[..., None] * axis
    return TwoBoneSolution(mid, end, normal, (l1, l2))
