"""The built-in human (paper Table 3's biped)."""

from rigmap.rigs.manifest import RigManifest

MANIFEST = RigManifest(
    name="biped",
    factory="rigmap.rigs.characters.biped:build_biped",
    label="Biped",
    library="rigmap.animation.library.biped",
    script="rigmap.retarget.biped_script:retarget_biped",
    report_order=1,
)
