"""The built-in dog (paper Table 3's quadruped)."""

from rigmap.rigs.manifest import character

MANIFEST = character("quadruped", "Quadruped", script=True, report_order=0)
