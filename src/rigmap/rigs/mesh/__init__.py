"""Mesh rigs: procedural surfaces and torch deformers (blendshapes, combination
correctives, linear blend skinning, Bernstein lattices, a collision corrective)
behind the Rig protocol, for the face and squirrel characters (paper §6.3)."""

from rigmap.rigs.mesh.blendshapes import Blendshapes, CombinationShapes, CombinationSpec, ShapeSpec
from rigmap.rigs.mesh.collision import CollisionSink
from rigmap.rigs.mesh.geometry import MeshAssembly, TriangleMesh
from rigmap.rigs.mesh.lattice import BernsteinLattice
from rigmap.rigs.mesh.rig import DeformedMesh, MeshRig
from rigmap.rigs.mesh.skinning import Bone, LinearBlendSkin, Skeleton

__all__ = [
    "BernsteinLattice",
    "Blendshapes",
    "Bone",
    "CollisionSink",
    "CombinationShapes",
    "CombinationSpec",
    "DeformedMesh",
    "LinearBlendSkin",
    "MeshAssembly",
    "MeshRig",
    "ShapeSpec",
    "Skeleton",
    "TriangleMesh",
]
