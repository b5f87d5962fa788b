"""``MeshRig``: a rig whose output is points on a deformed mesh.

The deformer stack (blendshapes, skinning, lattices, correctives) lives in a
subclass's ``_deform``, written once in torch. This base class gives it the
Rig protocol: input checking (from :class:`Rig`), numpy in -> numpy out
(evaluated without autograd, in chunks), torch in -> torch out with gradients,
float32 or float64. Its "joints" are a chosen set of mesh vertices (landmarks
on a face, every vertex of the squirrel), relative to the centre of gravity.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import NamedTuple

import numpy as np
import torch

from rigmap.rigs.base import Control, ControlTable, Pose, Rig, _is_torch

# Poses per chunk when evaluating numpy input; bounds memory at roughly
# chunk x vertices x 12 floats for the skinning blend.
DEFAULT_CHUNK = 2048


class DeformedMesh(NamedTuple):
    """World vertices ``(N, V', 3)`` (cm) and the COG placement (``(N, 3)``, ``(N, 3, 3)``)."""

    vertices: torch.Tensor
    cog: torch.Tensor
    cog_rotation: torch.Tensor


class MeshRig(Rig):
    """A differentiable torch mesh rig; subclasses implement :meth:`_deform`."""

    differentiable = True
    parents = None

    def __init__(
        self,
        *,
        name: str,
        controls: list[Control],
        rest_vertices: np.ndarray,
        faces: np.ndarray,
        joint_vertices: np.ndarray,
        joint_names: list[str],
        description: str = "",
        face_colors: np.ndarray | None = None,
        chunk: int = DEFAULT_CHUNK,
    ):
        self.name = name
        self.description = description
        self.controls = ControlTable(controls)
        self.rest_vertices = np.asarray(rest_vertices, dtype=np.float64)
        self.faces = np.asarray(faces, dtype=np.int64)
        n_vertices = len(self.rest_vertices)
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise ValueError(f"rig {name!r}: faces must be (F, 3), got {self.faces.shape}")
        if self.faces.min() < 0 or self.faces.max() >= n_vertices:
            raise ValueError(f"rig {name!r}: face indices outside [0, {n_vertices})")
        self.joint_vertices = np.asarray(joint_vertices, dtype=np.int64)
        if len(joint_names) != len(self.joint_vertices):
            raise ValueError(
                f"rig {name!r}: {len(joint_names)} joint names for "
                f"{len(self.joint_vertices)} joint vertices"
            )
        self.joint_names = list(joint_names)
        self.face_colors = None if face_colors is None else np.asarray(face_colors, np.float64)
        self._all_joints = np.array_equal(self.joint_vertices, np.arange(n_vertices))
        self._chunk = int(chunk)
        self._constants: dict[tuple[str, torch.dtype], torch.Tensor] = {}

    @property
    def n_vertices(self) -> int:
        return len(self.rest_vertices)

    # --- the protocol -----------------------------------------------------
    def _pose(self, Y) -> Pose:
        joints = None if self._all_joints else self.joint_vertices

        def pose_of(Yt: torch.Tensor) -> Pose:
            mesh = self._deform(Yt, joints)
            return Pose(mesh.vertices - mesh.cog[:, None, :], mesh.cog, mesh.cog_rotation)

        return _run(Y, pose_of, self._chunk)

    def mesh(self, Y):
        """Every deformed vertex relative to the COG: ``(N, V, 3)``, or ``(V, 3)`` for one pose."""
        Y, squeeze = self._check_controls(Y)

        def vertices_of(Yt: torch.Tensor) -> tuple[torch.Tensor]:
            mesh = self._deform(Yt, None)
            return (mesh.vertices - mesh.cog[:, None, :],)

        (vertices,) = _run(Y, vertices_of, self._chunk)
        return vertices[0] if squeeze else vertices

    def world_vertices(self, Y):
        """Every deformed vertex in the world (cm, not relative to the COG): ``(N, V, 3)``, or
        ``(V, 3)`` for one pose. One deformation gives a drawn surface and, at
        :attr:`joint_vertices`, the joints: a viewer needs no second evaluation."""
        Y, squeeze = self._check_controls(Y)
        (vertices,) = _run(Y, lambda Yt: (self._deform(Yt, None).vertices,), self._chunk)
        return vertices[0] if squeeze else vertices

    @abstractmethod
    def _deform(self, Y: torch.Tensor, vertex_index: np.ndarray | None) -> DeformedMesh:
        """Deform the mesh for an ``(N, C)`` batch; only ``vertex_index`` vertices if given."""

    # --- helpers for subclasses --------------------------------------------
    def constant(self, key: str, array, dtype: torch.dtype) -> torch.Tensor:
        """A build-time array as a torch constant, converted once per dtype."""
        cached = self._constants.get((key, dtype))
        if cached is None:
            cached = torch.as_tensor(np.asarray(array, dtype=np.float64), dtype=dtype)
            self._constants[(key, dtype)] = cached
        return cached

    def column(self, Y: torch.Tensor, control: str) -> torch.Tensor:
        """One control's ``(N,)`` values by name."""
        return Y[:, self.controls.index(control)]


def _run(Y, fn, chunk: int):
    """Call ``fn`` on torch input directly, or on numpy input chunk by chunk without autograd."""
    if _is_torch(Y):
        return fn(Y)
    dtype = torch.float32 if Y.dtype == np.float32 else torch.float64
    parts = []
    with torch.no_grad():
        for start in range(0, max(len(Y), 1), chunk):
            Yt = torch.as_tensor(np.ascontiguousarray(Y[start : start + chunk]), dtype=dtype)
            parts.append(fn(Yt))
    out = tuple(np.concatenate([p[k].numpy() for p in parts]) for k in range(len(parts[0])))
    return Pose(*out) if isinstance(parts[0], Pose) else out
