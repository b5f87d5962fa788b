"""Rigify's wolf, evaluated by Blender workers; the dog's motions re-keyed onto its controls."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="rigify_wolf",
    factory="rigmap.rigs.blender.rigify:build_rigify_wolf",
    label="Rigify Wolf (Blender)",
    library="rigmap.animation.library.wolf",
    report_order=4,
    extra=True,
)
