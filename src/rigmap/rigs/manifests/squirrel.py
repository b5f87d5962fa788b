"""The built-in squirrel (paper Table 3's squirrel): a mesh rig with a body and a face."""

from rigmap.rigs.manifest import character

MANIFEST = character("squirrel", "Squirrel", report_order=3)
