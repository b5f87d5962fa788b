"""Linear blend skinning and the bone hierarchy that drives it.

Each bone has a rest frame (a :class:`Transform`; world-aligned axes at a
pivot, in cm) and a posed frame. A vertex moves by the weighted blend of its
bones' *skinning transforms* ``posed ∘ rest⁻¹`` — the classic LBS (Magnenat-
Thalmann et al.), batched and differentiable. Weights are per vertex, sum to
one and are fixed at build time.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from rigmap.rigs.engine.transforms import Transform
from rigmap.rigs.mesh.lattice import blend_rows


@dataclass(frozen=True)
class Bone:
    """A bone: name, parent bone name (``None`` for the root) and rest pivot (cm)."""

    name: str
    parent: str | None
    pivot: tuple[float, float, float]


class Skeleton:
    """Bones in parent-before-child order, with forward kinematics about rest pivots."""

    def __init__(self, bones: Sequence[Bone]):
        self.bones = list(bones)
        self.names = [b.name for b in self.bones]
        self.index = {name: i for i, name in enumerate(self.names)}
        if len(self.index) != len(self.names):
            raise ValueError(f"duplicate bone names in {self.names}")
        for i, b in enumerate(self.bones):
            if b.parent is not None and self.index.get(b.parent, len(self.bones)) >= i:
                raise ValueError(f"bone {b.name!r}: parent {b.parent!r} must come before it")
        self.pivots = np.array([b.pivot for b in self.bones], dtype=np.float64)

    def __len__(self) -> int:
        return len(self.bones)

    def forward_kinematics(
        self, rest: Sequence[Transform], local: dict[str, torch.Tensor]
    ) -> list[Transform]:
        """Posed world frames from rest frames and local ``(N, 3, 3)`` matrices.

        ``rest[b]`` is bone b's rest frame (possibly already carried by a
        lattice); ``local[name]`` the matrix applied in the bone's own frame
        (a rotation, or a rotation times a squash). Bones without an entry keep
        their rest offset to the parent.
        """
        posed: list[Transform] = []
        for i, b in enumerate(self.bones):
            if b.parent is None:
                frame = rest[i]
            else:
                p = self.index[b.parent]
                offset = _rigid_inverse(rest[p]).compose(rest[i])
                frame = posed[p].compose(offset)
            if b.name in local:
                M = local[b.name]
                frame = frame.compose(Transform(M, torch.zeros_like(frame.t)))
            posed.append(frame)
        return posed


def skinning_transforms(rest: Sequence[Transform], posed: Sequence[Transform]) -> Transform:
    """Per-bone ``posed ∘ rest⁻¹`` stacked as ``R (N, B, 3, 3)``, ``t (N, B, 3)``."""
    skins = [p.compose(_rigid_inverse(r)) for r, p in zip(rest, posed, strict=True)]
    return Transform(
        torch.stack([s.R for s in skins], dim=1), torch.stack([s.t for s in skins], dim=1)
    )


class LinearBlendSkin:
    """Fixed per-vertex weights ``(V, B)`` over a skeleton's bones."""

    def __init__(self, weights: np.ndarray, bone_names: Sequence[str]):
        weights = np.asarray(weights, dtype=np.float64)
        if weights.ndim != 2 or weights.shape[1] != len(bone_names):
            raise ValueError(
                f"skin weights must be (V, {len(bone_names)}) for bones {list(bone_names)}, "
                f"got {weights.shape}"
            )
        if np.any(weights < -1e-12):
            raise ValueError("skin weights must be non-negative")
        sums = weights.sum(axis=1)
        if not np.allclose(sums, 1.0, atol=1e-9):
            worst = int(np.argmax(np.abs(sums - 1.0)))
            raise ValueError(f"skin weights of vertex {worst} sum to {sums[worst]:.6f}, not 1")
        self.weights = weights
        self.bone_names = list(bone_names)

    def apply(
        self, vertices: torch.Tensor, skins: Transform, weights: torch.Tensor
    ) -> torch.Tensor:
        """Skin ``(N, V, 3)`` vertices with ``(N, B)`` skinning transforms and ``(V, B)`` weights.

        The blended affine map of each vertex is built first (``(N, V, 12)``)
        so the cost is one small matrix product per pose, not one per bone.
        """
        n, b = skins.t.shape[0], skins.t.shape[1]
        affine = torch.cat([skins.R.reshape(n, b, 9), skins.t], dim=2)  # (N, B, 12)
        blended = blend_rows(weights, affine)  # (N, V, 12), a view of a (V, N, 12) array
        return apply_blended(blended[..., :9], vertices) + blended[..., 9:]


def apply_blended(matrices: torch.Tensor, vectors: torch.Tensor) -> torch.Tensor:
    """Per-vertex ``(N, V, 9)`` row-major 3x3 matrices times ``(N, V, 3)`` vectors.

    Written as three row products rather than a batched 3x3 matmul so the
    matrices are never copied into a contiguous ``(N, V, 3, 3)`` block.
    """
    rows = [(matrices[..., 3 * i : 3 * i + 3] * vectors).sum(-1) for i in range(3)]
    return torch.stack(rows, dim=-1)


def _rigid_inverse(frame: Transform) -> Transform:
    """Inverse of a rotation + translation (rest frames are rigid)."""
    Rt = frame.R.transpose(-1, -2)
    return Transform(Rt, -(Rt @ frame.t[..., None])[..., 0])
