"""The script baseline for Blender rigs: constraint-based retargeting (issue item 6).

Empties at the target joint positions, constraints from the rig's controls to
them (copy location, copy rotation/transforms for the COG, damped track), then
each control's visual transform read back as channel values — what a TD would
script by hand. The mapping (which control follows which joint how) is rig
data: ``retarget`` in the rig config, or the ``mapping`` argument; each entry is
``{bone, type, target}`` with ``target`` a joint name or ``"cog"`` (the COG
placement, the only oriented target), and ``offset: true`` to keep the rest
offset between a control and a joint it does not sit on (a wolf's foot IK).

This module works on a built :class:`~rigmap.rigs.blender.rig.BlenderRig` (it is
what the rig's ``constraint_retarget`` method runs); the entry point that also
takes a rig name or config is :func:`rigmap.rigs.blender.lookup.constraint_retarget`.
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.base import Pose, check_placement, check_positions

CONSTRAINT_TYPES = ("COPY_LOCATION", "COPY_ROTATION", "COPY_TRANSFORMS", "DAMPED_TRACK")


def _check_mapping(rig, mapping: list[dict]) -> list[dict]:
    if not mapping:
        raise ValueError(
            f"rig {rig.name!r} has no retarget mapping: give mapping=[{{bone, type, target}}, ...] "
            "or a 'retarget' list in the rig config"
        )
    plain = []
    for i, entry in enumerate(mapping):
        entry = dict(entry)
        missing = {"bone", "type", "target"} - set(entry)
        if missing:
            raise ValueError(f"retarget mapping entry {i} ({entry}) lacks {sorted(missing)}")
        if entry["type"] not in CONSTRAINT_TYPES:
            raise ValueError(
                f"retarget mapping entry {i}: type {entry['type']!r} not in {CONSTRAINT_TYPES}"
            )
        if entry["target"] != "cog" and entry["target"] not in rig.joint_names:
            raise ValueError(
                f"retarget mapping entry {i}: target {entry['target']!r} is neither 'cog' nor a "
                f"joint of rig {rig.name!r}"
            )
        plain.append(entry)
    return plain


def solve_constraints(rig, positions, cog=None, cog_rotation=None, *, mapping=None):
    """Control vectors ``(N, C)`` that make the mapped controls of Blender ``rig`` follow the
    target joints.

    ``positions``: ``(N, J, 3)`` COG-relative joint positions (cm) or a
    :class:`~rigmap.rigs.base.Pose` (then ``cog`` and ``cog_rotation`` come from
    it). Controls the mapping does not touch stay at their defaults.
    """
    if isinstance(positions, Pose):
        positions, cog, cog_rotation = positions
    where = f"constraint_retarget on rig {rig.name!r}"
    X = check_positions(positions, rig.n_joints, where)
    n = len(X)
    if np.ndim(cog) == 1 and np.ndim(cog_rotation) == 2:
        cog, cog_rotation = np.asarray(cog)[None], np.asarray(cog_rotation)[None]  # one frame
    cog, cog_rotation = check_placement(cog, cog_rotation, n, where)
    plain = _check_mapping(rig, mapping if mapping is not None else rig.retarget_mapping)
    # One worker, frames in order: Euler angles stay continuous from frame to frame.
    _, out = rig.pool.call(
        "retarget",
        {"mapping": plain},
        {"positions": X, "cog": cog, "cog_rotation": cog_rotation},
        timeout=rig.timeout + 0.1 * n,
    )
    return out["controls"]
