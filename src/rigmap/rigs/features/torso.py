"""The torso: placement root, centre of gravity, hips and chest, and the spline spine between.

One unit for every body rig (the biped and the dog). Its controls:

- ``root`` on the ground (``tx tz ry`` keyed: travel and heading), ±300 cm;
- ``cog`` under the root (all six channels keyed), ±60 cm so the body can crouch,
  kneel or lie down;
- ``hips`` and ``chest`` under the COG (the chest also translates), and
  ``spine_mid`` pulling the middle of the :func:`~.spline_spine.spline_spine`.

The soft ranges are ours (the paper gives none); they cover the library's clips.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from rigmap.rigs.engine.builder import RigBuilder
from rigmap.rigs.features.spline_spine import spline_spine

GROUP = "torso"


@dataclass(frozen=True)
class TorsoSpec:
    """Rest offsets (cm): the COG from the root, hips, chest and spine mid from the COG."""

    cog: Sequence[float]
    hips: Sequence[float]
    chest: Sequence[float]
    spine_mid: Sequence[float]
    spine: Sequence[str]  # spine joints, pelvis first, chest last


def torso(b: RigBuilder, spec: TorsoSpec) -> None:
    """Add root, COG, hips, chest, spine mid and the spine joints (the first has no parent)."""
    b.transform_control("root", parent=None, group="root", used="tx tz ry", translate_range=300.0)
    controls = {
        name: b.transform_control(
            name, parent=parent, offset=offset, group=GROUP, used=used, **ranges
        )
        for name, parent, offset, used, ranges in (
            ("cog", "root", spec.cog, "tx ty tz rx ry rz", {"translate_range": 60.0}),
            ("hips", "cog", spec.hips, "rx ry rz", {"rotate_range": 0.8}),
            ("chest", "cog", spec.chest, "tx ty tz rx ry rz", {"rotate_range": 1.0}),
            ("spine_mid", "cog", spec.spine_mid, "tx ty tz", {"translate_range": 15.0}),
        )
    }
    spline_spine(
        b,
        list(spec.spine),
        hips="hips",
        chest="chest",
        mid=controls["spine_mid"],
        parent_joint=None,
        group=GROUP,
    )
