"""The built-in face (paper Table 3's face): a mesh rig, its expressions read from the front."""

from rigmap.rigs.manifest import character

MANIFEST = character("face", "Face", view="front", report_order=2)
