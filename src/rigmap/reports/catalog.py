"""What the report's rig rows are called and in which order they appear.

The rigs come from their manifests; methods, samplers and kernels from
:mod:`rigmap.catalog` (each part's yaml or class), which a report's settings hold.
"""

from __future__ import annotations

from rigmap.catalog import Row
from rigmap.rigs.manifest import all_manifests, reported


def rig_rows() -> tuple[Row, ...]:
    """The reported rigs from their manifests, in the order of the paper's Table 3, then the
    Blender rigs (a rig registered later joins them)."""
    return tuple(Row(m.name, m.label, extra=m.extra) for m in reported())


#: the built-in characters as they stood when this module was imported (see ``rig_rows``)
RIGS: tuple[Row, ...] = rig_rows()


def rig_label(name: str) -> str:
    """``quadruped`` -> ``Quadruped`` (the manifest's label); unknown rigs keep their own name."""
    known = all_manifests().get(name)
    return name if known is None else known.label
