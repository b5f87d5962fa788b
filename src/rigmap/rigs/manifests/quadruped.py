"""The built-in dog (paper Table 3's quadruped)."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="quadruped",
    factory="rigmap.rigs.characters.quadruped:build_quadruped",
    label="Quadruped",
    library="rigmap.animation.library.quadruped",
    script="rigmap.retarget.quadruped_script:retarget_quadruped",
    report_order=0,
)
