"""The rig run forward from placement-free targets, in the frame the regressor's inputs live in.

A regressor behind a :class:`~rigmap.regression.placement.Placement` predicts
*targets*: the used controls with the root channels replaced by the root
pivot's offset from the COG (ground columns, cm) and the COG's heading relative
to the root's (turn column, radians). :meth:`Placement.controls` turns them
into controls from the target's COG placement; the rig then gives world
poses. Training through the rig needs the same answer differentiably and
without the target's world placement, and it exists in closed form:

- evaluate the rig on the targets with every root channel at zero (``p0``: the
  COG-relative joints, ``c0``: the COG, both in world axes);
- the placement would turn that pose by ``h - t`` about +Y (``h`` the target's
  heading, ``t`` the predicted turn column), so in the target's heading frame
  (``R(h)^T``, the frame of :meth:`Placement.inputs`) the joints are
  ``R(-t) p0`` — whatever ``h`` is;
- the predicted COG, relative to the target COG in that frame, is
  ``o + R(-t) (c0 - pivot_rest)`` on the ground plane (``o`` the predicted
  ground offsets) and ``c0_y`` in height.

So the joint error of ``rig(placement.controls(targets))`` against the target
pose equals that of :meth:`PlacedRigForward.__call__` against the regressor's
own inputs (``tests/test_joint_space_network.py`` checks it against the numpy
path). Rigs without root channels (a face) compare raw COG-relative joints and
the COG's world position.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import torch

from rigmap.errors import RigmapError
from rigmap.regression.placement import UP, Placement


class NotDifferentiableRigError(RigmapError, TypeError):
    """Training through the rig was asked of a rig that cannot give gradients (a DCC rig)."""


class PlacedPose(NamedTuple):
    """Joints ``(N, J, 3)`` and COG ``(N, 3)`` in the placement's input frame (cm)."""

    joints: torch.Tensor
    cog: torch.Tensor


def require_differentiable(rig, who: str) -> None:
    """A clear error for a rig torch cannot differentiate (Blender workers)."""
    if not getattr(rig, "differentiable", False):
        raise NotDifferentiableRigError(
            f"{who} trains through the rig, but rig {rig.name!r} is not differentiable (it is "
            "evaluated by worker processes, e.g. Blender). Training it needs a learned forward "
            "surrogate of the rig (rigmap.regression.stand_in fits one, but training through "
            "it is not wired in yet); use regressor=nn or regressor=gpr for this rig"
        )


def _turn(angle: torch.Tensor) -> torch.Tensor:
    """``(N, 3, 3)`` rotations by ``angle`` about +Y (as ``placement.turn_matrix``)."""
    c, s = torch.cos(angle), torch.sin(angle)
    zero, one = torch.zeros_like(angle), torch.ones_like(angle)
    rows = [torch.stack([c, zero, s], -1), torch.stack([zero, one, zero], -1)]
    rows.append(torch.stack([-s, zero, c], -1))
    return torch.stack(rows, -2)


class PlacedRigForward:
    """``targets (N, C_used) -> PlacedPose``: the differentiable rig behind a placement.

    ``compiled_rows``: run the rig through its inductor-compiled pass of that many rows
    (:meth:`TorchRig.compiled_pose`) instead of its eager one; ``None`` keeps the eager pass.
    """

    def __init__(
        self,
        rig,
        placement: Placement,
        who: str = "training through the rig",
        compiled_rows: int | None = None,
    ):
        require_differentiable(rig, who)
        if compiled_rows is not None and not hasattr(rig, "compiled_pose"):
            raise NotDifferentiableRigError(
                f"{who}: rig {rig.name!r} has no compiled pass (only the built-in torch rigs "
                "have one); run it eagerly"
            )
        self.rig = rig
        self.compiled_rows = compiled_rows
        self.placement = placement
        self.root_columns = [c.index for c in placement.channels]
        self.ground = [c.index for c in placement.ground] if placement.ground else None
        self.turn = placement.turn.index if placement.turn is not None else None
        pivot = np.zeros(3)
        pivot[0], pivot[2] = placement.pivot_rest
        self.pivot_rest = torch.from_numpy(pivot)

    def __call__(self, targets: torch.Tensor) -> PlacedPose:
        zeroed = targets
        if self.root_columns:
            mask = torch.ones(targets.shape[1], dtype=targets.dtype)
            mask[self.root_columns] = 0.0
            zeroed = targets * mask
        controls = self.rig.expand_used(zeroed)
        if self.compiled_rows is None:
            pose = self.rig.pose(controls)
        else:
            pose = self.rig.compiled_pose(controls, self.compiled_rows)
        joints, cog = pose.positions, pose.cog
        if self.ground is None:
            return PlacedPose(joints, cog)
        if self.turn is not None:
            back = _turn(-targets[:, self.turn])  # R(-t)
            joints = torch.einsum("nab,njb->nja", back, joints)
            from_pivot = torch.einsum("nab,nb->na", back, cog - self.pivot_rest.to(cog.dtype))
        else:
            from_pivot = cog - self.pivot_rest.to(cog.dtype)
        offset = torch.zeros_like(cog)
        offset[:, 0], offset[:, 2] = targets[:, self.ground[0]], targets[:, self.ground[1]]
        placed = offset + from_pivot
        placed = torch.cat([placed[:, :UP], cog[:, UP : UP + 1], placed[:, UP + 1 :]], 1)
        return PlacedPose(joints, placed)

    def input_pose(self, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joints ``(N, J, 3)`` and COG ``(N, 3)`` a row of regressor inputs holds.

        Behind root channels the target COG is the frame's origin at its own height.
        """
        inputs = np.asarray(inputs, dtype=np.float64)
        n, width = len(inputs), 3 * self.rig.n_joints
        joints = inputs[:, :width].reshape(n, -1, 3)
        if self.ground is None:
            return joints, inputs[:, width : width + 3]
        cog = np.zeros((n, 3))
        cog[:, UP] = inputs[:, width]
        return joints, cog
