"""Rigify's human, evaluated by Blender workers (no motion library, not in the report)."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="rigify_human",
    factory="rigmap.rigs.blender.rigify:build_rigify_human",
    label="Rigify Human (Blender)",
    extra=True,
)
