"""Any user .blend with an armature (``path`` required), evaluated by Blender workers."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    "blend_file", "rigmap.animation.blend_corpus:build_blend_file", "Blender file"
)
