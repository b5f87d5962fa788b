"""Any user .blend with an armature (``path`` required), evaluated by Blender workers."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="blend_file",
    factory="rigmap.rigs.blender.rigify:build_blend_file",
    label="Blender file",
    extra=True,
)
