"""The built-in face (paper Table 3's face): a mesh rig, its expressions read from the front."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="face",
    factory="rigmap.rigs.characters.face:build_face",
    label="Face",
    library="rigmap.animation.library.face",
    view="front",
    report_order=2,
)
