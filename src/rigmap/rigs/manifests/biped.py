"""The built-in human (paper Table 3's biped)."""

from rigmap.rigs.manifest import character

MANIFEST = character("biped", "Biped", script=True, report_order=1)
