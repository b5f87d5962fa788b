"""Rigify's human, evaluated by Blender workers (no motion library, not in the report)."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    "rigify_human", "rigmap.rigs.blender.rigify:build_rigify_human", "Rigify Human (Blender)"
)
