"""Joint tracks that name the rig's own joints: a partial input taken as it is (§6.3).

The paper poses its dog from the trajectories of its four feet alone (Fig. 6): the input is
a few of the rig's own joints, not another skeleton. A joint-tracks file (``.parquet``,
``.csv``, ``.npz``; :mod:`rigmap.map.tracks`) whose every joint is a joint of the rig —
``front_paw_l.x``, ``front_paw_l.y``, … for the quadruped's paws — needs no retarget map:
its positions are the rig's world joint positions, in the rig's axes (Y up, +Z forward, the
rig's left +X) and the tracks' stated unit (``map.unit``). A retarget map cannot say this
for a few separate joints (it rebuilds a chain of bones from one root), so ``rigmap map``
takes such tracks directly (:func:`rig_joint_targets`) and maps them with the joint subset
``map.subset`` names (e.g. ``feet``).
"""

from __future__ import annotations

import numpy as np

from rigmap.map.joint_map import MappedTargets
from rigmap.map.tracks import LENGTH_UNITS_CM, JointTracks


def names_rig_joints(tracks: JointTracks, rig) -> bool:
    """Whether every joint of ``tracks`` is one of ``rig``'s joints (in a stated unit)."""
    joints = set(rig.joint_names)
    return tracks.unit in LENGTH_UNITS_CM and all(n in joints for n in tracks.joint_names)


def rig_joint_targets(tracks: JointTracks, rig) -> MappedTargets:
    """``tracks`` of ``rig``'s own joints as its targets: world cm, in the rig's joint order;
    the rig's other joints are listed as undriven."""
    if not names_rig_joints(tracks, rig):
        others = [n for n in tracks.joint_names if n not in rig.joint_names]
        raise ValueError(
            f"{tracks.source}: joints {others} are not joints of rig {rig.name!r} "
            f"(or the unit {tracks.unit!r} is not a length unit)"
        )
    names = tuple(n for n in rig.joint_names if n in tracks.joint_names)
    scale = LENGTH_UNITS_CM[tracks.unit]
    positions = tracks.subset(names).positions * scale
    undriven = tuple(n for n in rig.joint_names if n not in names)
    return MappedTargets(
        rig.name, names, np.asarray(positions), tracks.fps, tracks.source, scale, undriven, ()
    )
