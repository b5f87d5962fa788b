"""The built-in squirrel (paper Table 3's squirrel): a mesh rig with a body and a face."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="squirrel",
    factory="rigmap.rigs.characters.squirrel:build_squirrel",
    label="Squirrel",
    library="rigmap.animation.library.squirrel",
    report_order=3,
)
