"""The script baseline for Blender rigs: constraint-based retargeting (issue item 6).

Empties at the target joint positions, constraints from the rig's controls to
them (copy location, copy rotation/transforms for the COG, damped track), then
each control's visual transform read back as channel values — what a TD would
script by hand. The mapping (which control follows which joint how) is rig
data: ``retarget`` in the rig config, or the ``mapping`` argument; each entry is
``{bone, type, target}`` with ``target`` a joint name or ``"cog"`` (the COG
placement, the only oriented target), and ``offset: true`` to keep the rest
offset between a control and a joint it does not sit on (a wolf's foot IK).
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.base import Pose, RigInputError, check_positions
from rigmap.rigs.blender.export import blender_rig

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


def constraint_retarget(rig_config_or_rig, positions, cog=None, cog_rotation=None, *, mapping=None):
    """Control vectors ``(N, C)`` that make the mapped controls follow the target joints.

    ``positions``: ``(N, J, 3)`` COG-relative joint positions (cm) or a
    :class:`~rigmap.rigs.base.Pose` (then ``cog`` and ``cog_rotation`` come from
    it). Controls the mapping does not touch stay at their defaults.
    """
    rig = blender_rig(rig_config_or_rig)
    if isinstance(positions, Pose):
        positions, cog, cog_rotation = positions
    where = f"constraint_retarget on rig {rig.name!r}"
    X = check_positions(positions, rig.n_joints, where)
    n = len(X)
    if cog is None or cog_rotation is None:
        raise RigInputError(
            f"{where}: needs the COG placement (cog (N, 3), cog_rotation (N, 3, 3))"
        )
    cog = np.asarray(cog, dtype=np.float64)
    cog_rotation = np.asarray(cog_rotation, dtype=np.float64)
    if cog.ndim == 1 and cog_rotation.ndim == 2:  # one frame
        cog, cog_rotation = cog[None], cog_rotation[None]
    if cog.shape != (n, 3) or cog_rotation.shape != (n, 3, 3):
        raise RigInputError(
            f"{where}: expected cog ({n}, 3) and cog_rotation ({n}, 3, 3), "
            f"got {cog.shape} and {cog_rotation.shape}"
        )
    if not (np.isfinite(cog).all() and np.isfinite(cog_rotation).all()):
        raise RigInputError(f"{where}: cog or cog_rotation contains NaN or infinity")
    plain = _check_mapping(rig, mapping if mapping is not None else rig.retarget_mapping)
    # One worker, frames in order: Euler angles stay continuous from frame to frame.
    _, out = rig.pool.call(
        "retarget",
        {"mapping": plain},
        {"positions": X, "cog": cog, "cog_rotation": cog_rotation},
        timeout=rig.timeout + 0.1 * n,
    )
    return out["controls"]
