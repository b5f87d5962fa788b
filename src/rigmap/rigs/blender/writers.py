"""Which writer turns a rig's controls into a .blend (one place for every command that
writes one: ``rigmap synth``, the studio's Pose page)."""

from __future__ import annotations

from rigmap.rigs.blender.export import export_blend
from rigmap.rigs.blender.lookup import NotBlenderRigError
from rigmap.rigs.blender.rig import BlenderRig
from rigmap.rigs.blender.shape_keys import export_shape_key_blend


def blend_writer(rig):
    """How ``rig``'s controls become a .blend: keys on a Blender rig's own controls
    (:func:`rigmap.rigs.blender.export.export_blend`), or shape keys on a mesh rig's mesh
    (:func:`rigmap.rigs.blender.shape_keys.export_shape_key_blend`). Either is called as
    ``writer(rig, table, path, fps=..., action_name=...)`` with a ``frame`` column and one
    column per control."""
    if isinstance(rig, BlenderRig):
        return export_blend
    if callable(getattr(rig, "mesh", None)) and getattr(rig, "faces", None) is not None:
        return export_shape_key_blend
    raise NotBlenderRigError(
        f"rig {rig.name!r} has neither a Blender file nor a mesh to write a .blend of"
    )
