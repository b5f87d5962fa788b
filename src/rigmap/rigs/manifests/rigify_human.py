"""Rigify's human, evaluated by Blender workers; the biped's motions re-keyed onto its controls."""

from rigmap.rigs.manifest import RigManifest

FACTORY = "rigmap.rigs.blender.rigify:build_rigify_human"
LIBRARY = "rigmap.animation.library.rigify_human"

MANIFEST = RigManifest("rigify_human", FACTORY, "Rigify Human (Blender)", LIBRARY)
