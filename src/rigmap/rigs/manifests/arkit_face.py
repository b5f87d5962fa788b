"""The built-in face driven by ARKit's 52 blendshapes (Live Link Face curves); no motion
library of its own: its motion is a user's captured takes."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    "arkit_face",
    "rigmap.rigs.characters.arkit_face:build_arkit_face",
    "ARKit face",
    view="front",
    extra=True,
)
