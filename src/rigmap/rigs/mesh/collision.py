"""A collision corrective: a surface region sinks away from collider points.

The squirrel's neck and chest must give way when the head bends down so the
teeth never enter the body (paper §6.3, Fig. 9). Rather than one sculpted
dent keyed to the neck angle (which fits only the poses it was sculpted for),
the dent follows the teeth. Each region vertex has a *sink direction* ``d`` (into
the body; for the squirrel the body's backward axis, carried by its lattice,
so it varies slowly over the region). Seen along it the region is a height
field; a vertex that has a collider point within ``reach`` sideways and less
than ``margin`` in front of it (or already behind it) retreats along ``d`` by
the missing depth. Neighbouring vertices move in nearly the same direction, so
the dented surface does not fold, and a triangle whose corners all lie behind
a point lies behind it too — the colliders end up in front of the surface
however deep they would have gone.

The pieces are smooth (C1) *and* exactly zero away from contact: a quadratic
ramp for ``max(0, depth + margin)`` (never below it), a smoothstep footprint
between ``reach`` and ``reach_out``, for the max over points their mean
weighted by ``n exp(k n)`` (zeros weigh nothing). So the rig stays
differentiable, the corrective is exactly inactive when nothing is near, and
(pose, vertex) pairs that no collider group can reach (bounding-ball test)
skip the pairwise work. It is a pure function of the
controls that move the colliders (neck bend, neck and head rotations, body
lattice): a driven corrective.
"""

from __future__ import annotations

import itertools

import numpy as np
import torch


class CollisionSink:
    """Pushes ``region`` vertices along their sink directions, behind collider vertices."""

    def __init__(
        self,
        rest_vertices: np.ndarray,
        region: np.ndarray,
        region_weight: np.ndarray,
        colliders: np.ndarray,
        *,
        margin: float = 0.5,
        reach: float = 2.8,
        reach_out: float = 3.6,
        softness: float = 0.25,
        max_sharpness: float = 12.0,
        group_size: int = 5,
    ):
        """Mesh vertex indices of the sinking ``region`` (painted 0..1 weights) and colliders.

        Colliders are clustered into compact groups of about ``group_size``
        so that poses can be skipped by one bounding-ball test per group. ``margin``,
        ``reach``, ``reach_out`` and ``softness`` (half-width of the ramp's
        rounded corner) are in cm; ``max_sharpness`` (1/cm) sets how closely
        the smooth max over points follows the max (it never exceeds it).
        """
        self.region = np.asarray(region, dtype=np.int64)
        self.region_weight = np.asarray(region_weight, dtype=np.float64)
        self.colliders = np.asarray(colliders, dtype=np.int64)
        if len(self.colliders) == 0:
            raise ValueError("collision corrective needs collider vertices")
        self.groups = _compact_groups(np.asarray(rest_vertices), self.colliders, group_size)
        self.colliders = np.concatenate(self.groups)  # group by group, so groups are slices
        bounds = np.cumsum([0, *(len(g) for g in self.groups)])
        self._group_slices = [slice(a, b) for a, b in itertools.pairwise(bounds)]
        if len(self.region) != len(self.region_weight):
            raise ValueError(
                f"{len(self.region)} region vertices, {len(self.region_weight)} weights"
            )
        if len(self.region) == 0:
            raise ValueError("collision corrective needs region vertices")
        if np.intersect1d(self.region, self.colliders).size:
            raise ValueError("a vertex cannot be both in the sinking region and a collider")
        if np.any((self.region_weight < 0) | (self.region_weight > 1)):
            raise ValueError("region weights must lie in [0, 1]")
        if not 0 < reach < reach_out:
            raise ValueError(f"need 0 < reach < reach_out, got {reach}, {reach_out}")
        self.margin = float(margin)
        self.reach = float(reach)
        self.reach_out = float(reach_out)
        self.softness = float(softness)
        self.max_sharpness = float(max_sharpness)

    def push(self, vertices: torch.Tensor, direction: torch.Tensor, weight: torch.Tensor):
        """``(N, R, 3)`` displacements (cm) of the region vertices.

        ``vertices (N, V, 3)`` is the mesh before the corrective, ``direction
        (N, R, 3)`` the unit sink direction of each region vertex, ``weight
        (R,)`` the region weights as a tensor of the right dtype. Only the
        (pose, region vertex) pairs that a collider group may reach are
        computed; every other push is exactly zero anyway.
        """
        shape = (vertices.shape[0], len(self.region), 3)
        reachable = self._may_touch(vertices.detach(), direction.detach())
        pose, vertex = torch.nonzero(reachable, as_tuple=True)
        if len(pose) == 0:
            return vertices.new_zeros(shape)
        region = torch.as_tensor(self.region)
        surface = vertices[pose, region[vertex]]  # (M, 3)
        d = direction[pose, vertex]  # (M, 3)
        points = vertices[:, self.colliders][pose]  # (M, P, 3)
        amount = self._amount(surface, d, points) * weight[vertex]
        return vertices.new_zeros(shape).index_put((pose, vertex), amount[:, None] * d)

    def _may_touch(self, vertices: torch.Tensor, direction: torch.Tensor) -> torch.Tensor:
        """``(N, R)`` False only where no collider can push that region vertex in that pose.

        Each collider group is replaced by its bounding ball (centroid, radius
        this pose): a point of the ball is at most ``radius`` deeper and at
        least ``radius`` less far sideways than the centroid.
        """
        surface = vertices[:, self.region]  # (N, R, 3)
        points = vertices[:, self.colliders]
        groups = [points[:, part] for part in self._group_slices]
        centers = torch.stack([g.mean(dim=1) for g in groups], dim=1)  # (N, G, 3)
        radius = torch.stack(
            [
                torch.linalg.vector_norm(g - centers[:, k, None], dim=-1).amax(dim=1)
                for k, g in enumerate(groups)
            ],
            dim=1,
        )[:, None, :]  # (N, 1, G)
        depth = direction @ centers.transpose(1, 2) - (surface * direction).sum(-1)[..., None]
        distance2 = (
            (centers * centers).sum(-1)[:, None, :]
            + (surface * surface).sum(-1)[..., None]
            - 2.0 * surface @ centers.transpose(1, 2)
        )
        sideways2 = torch.clamp(distance2 - depth * depth, min=0.0)
        deep_enough = depth + radius + self.margin > -self.softness
        near_enough = sideways2 < (self.reach_out + radius) ** 2
        return (deep_enough & near_enough).any(dim=2)

    def _amount(self, surface: torch.Tensor, direction: torch.Tensor, points: torch.Tensor):
        """``(M,)`` retreat (cm) of surface points ``(M, 3)`` along ``direction`` (M, 3).

        ``points (M, P, 3)`` are the colliders of each surface point's pose.
        """
        # depth of every point along d, relative to the surface point: (M, P)
        depth = (points @ direction[:, :, None])[..., 0] - (surface * direction).sum(-1)[:, None]
        distance2 = (
            (points * points).sum(-1)
            - 2.0 * (points @ surface[:, :, None])[..., 0]
            + (surface * surface).sum(-1)[:, None]
        )
        sideways2 = distance2 - depth * depth
        missing = rounded_ramp(depth + self.margin, self.softness)
        s = torch.clamp((self.reach_out**2 - sideways2) / (self.reach_out**2 - self.reach**2), 0, 1)
        need = missing * s * s * (3.0 - 2.0 * s)
        # a smooth max over points: their mean weighted by n exp(k n) — zeros carry no weight,
        # the exponential concentrates it on the largest (shifted by the max for range)
        top = need.detach().amax(dim=-1, keepdim=True)
        w = need * torch.exp(self.max_sharpness * (need - top))
        return (w * need).sum(-1) / (w.sum(-1) + 1e-30)


def _compact_groups(vertices: np.ndarray, indices: np.ndarray, size: int) -> list[np.ndarray]:
    """Cluster ``indices`` by rest position into about ``len / size`` compact groups.

    Farthest-point seeds then a few Lloyd (k-means) steps: deterministic, and
    the groups come out round, so their bounding balls are small.
    """
    points = vertices[indices]
    k = max(1, int(np.ceil(len(indices) / size)))
    seeds = [0]
    distance = np.linalg.norm(points - points[0], axis=1)
    for _ in range(k - 1):
        seeds.append(int(np.argmax(distance)))
        distance = np.minimum(distance, np.linalg.norm(points - points[seeds[-1]], axis=1))
    centers = points[seeds]
    for _ in range(10):
        label = np.argmin(np.linalg.norm(points[:, None] - centers[None], axis=2), axis=1)
        centers = np.array(
            [
                points[label == j].mean(axis=0) if np.any(label == j) else centers[j]
                for j in range(k)
            ]
        )
    return [indices[label == j] for j in range(k) if np.any(label == j)]


def rounded_ramp(x: torch.Tensor, softness: float) -> torch.Tensor:
    """``max(0, x)`` with its corner rounded over ``[-softness, softness]``: C1, never below it.

    Exactly 0 for ``x <= -softness`` and exactly ``x`` for ``x >= softness``.
    """
    h = softness
    t = torch.clamp(x + h, 0.0, 2.0 * h)
    return t * t / (4.0 * h) + torch.clamp(x - h, min=0.0)
