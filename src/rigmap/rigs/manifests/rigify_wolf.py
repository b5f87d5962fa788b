"""Rigify's wolf, evaluated by Blender workers; the dog's motions re-keyed onto its controls."""

from rigmap.rigs.manifest import RigManifest

FACTORY = "rigmap.rigs.blender.rigify:build_rigify_wolf"
LIBRARY = "rigmap.animation.library.wolf"

MANIFEST = RigManifest(
    "rigify_wolf", FACTORY, "Rigify Wolf (Blender)", LIBRARY, report_order=4, extra=True
)
