"""A rig seen through a joint subset in world space: what refinement on mapped targets needs.

Targets from mocap or effectors are *world* positions of a few joints, while the rig
protocol reports all joints relative to the COG (which cannot see the root's ground
translation). :class:`WorldSubsetRig` wraps a rig so that its "joints" are the subset's
world positions: every refiner and Jacobian source in :mod:`rigmap.refine` then works on
mapped targets unchanged, the root channels included. Its COG placement is the origin
with no rotation, so the positions it reports are the world positions themselves.
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.base import Pose, Rig, RigInputError


class WorldSubsetRig(Rig):
    """``evaluate(Y)`` = world positions ``(N, K, 3)`` of ``joints`` of the wrapped rig."""

    def __init__(
        self,
        rig: Rig,
        joints: list[str] | tuple[str, ...],
        *,
        traced: bool = False,
        keep_world: bool = False,
    ):
        unknown = [j for j in joints if j not in rig.joint_names]
        if unknown:
            raise RigInputError(f"rig {rig.name!r} has no joints {unknown}")
        self.inner = rig
        self.name = rig.name
        self.controls = rig.controls
        self.joint_names = list(joints)
        self.parents = None
        self.differentiable = rig.differentiable
        self.computes_in_float32 = getattr(rig, "computes_in_float32", False)
        self.length_unit = rig.length_unit
        self.description = f"{rig.name}: world positions of {len(joints)} joints"
        self._columns = [rig.joint_names.index(j) for j in joints]
        # numpy batches through the inner rig's cached TorchScript traces (built-in rigs):
        # the same numbers at about twice the rate on small batches (TorchRig.traced_pose)
        self.traced = traced and hasattr(rig, "traced_pose")
        #: with ``keep_world``: ``(N, J, 3)`` world positions of all the rig's joints at the
        #: last numpy batch (an interactive pose shows them; refinement does not need them)
        self.keep_world = keep_world
        self.last_world: np.ndarray | None = None

    def _pose(self, Y) -> Pose:
        traced = self.traced and isinstance(Y, np.ndarray)
        pose = self._traced_pose(Y) if traced else self.inner.pose(Y)
        world = pose.positions[:, self._columns] + pose.cog[:, None, :]
        if isinstance(world, np.ndarray):
            if self.keep_world:
                self.last_world = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
        else:  # a torch batch stays torch (differentiable)
            import torch

            zeros = torch.zeros_like(pose.cog)
            eye = torch.eye(3, dtype=pose.cog.dtype).expand(len(Y), 3, 3)
            return Pose(world, zeros, eye)
        n = len(world)
        return Pose(np.asarray(world), np.zeros((n, 3)), np.broadcast_to(np.eye(3), (n, 3, 3)))

    def _traced_pose(self, Y: np.ndarray) -> Pose:
        import torch

        dtype = torch.float32 if Y.dtype == np.float32 else torch.float64
        with torch.no_grad():
            out = self.inner.traced_pose(len(Y), dtype)(torch.from_numpy(np.ascontiguousarray(Y)))
        return Pose(*(part.numpy() for part in out))

    def close(self) -> None:
        self.inner.close()
