"""Blender as a black-box rig backend: Rigify rigs and user .blend files.

Blender runs in worker processes with their own Python (bpy pins numpy<2):
:mod:`.environment` finds it, :mod:`.worker_process` and :mod:`.pool` talk to
the workers (code in :mod:`.in_blender` runs inside them), :mod:`.rig` is the
:class:`~rigmap.rigs.base.Rig`, :mod:`.rigify` the built-in rigs, :mod:`.export`
writes control curves as keyframes into a .blend, :mod:`.shape_keys` a mesh rig's
animation as shape keys with an action, :mod:`.retarget` is the
constraint-based script baseline, :mod:`.lookup` finds a Blender rig by name or config.
"""

from rigmap.rigs.blender.environment import BlenderNotFoundError, blender_available, find_blender
from rigmap.rigs.blender.export import export_blend, read_blend_animation
from rigmap.rigs.blender.lookup import blender_rig, constraint_retarget
from rigmap.rigs.blender.rig import BlenderRig
from rigmap.rigs.blender.shape_keys import (
    ShapeKeyExportError,
    export_shape_key_blend,
    read_shape_key_blend,
    read_shape_key_mesh,
)
from rigmap.rigs.blender.worker_process import RequestTimeout, WorkerCrashed, WorkerError

__all__ = [
    "BlenderNotFoundError",
    "BlenderRig",
    "RequestTimeout",
    "ShapeKeyExportError",
    "WorkerCrashed",
    "WorkerError",
    "blender_available",
    "blender_rig",
    "constraint_retarget",
    "export_blend",
    "export_shape_key_blend",
    "find_blender",
    "read_blend_animation",
    "read_shape_key_blend",
    "read_shape_key_mesh",
]
