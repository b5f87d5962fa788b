"""The "Maya script" baseline (paper §6.1): a rig-specific heuristic retarget, no learning.

``script_retarget`` takes target joint positions (COG-relative) and the COG's
world placement, runs the script for the rig, and returns the used controls plus
the rig evaluations the script spent. This is the one place that picks the
script:

- built-in articulated rigs have a hand-written script (named by the rig's
  manifest, :mod:`rigmap.rigs.manifest`) that reads back parents' world transforms;
- Blender rigs with a ``retarget`` mapping run the constraint-based retarget
  (``rig.constraint_retarget``, :mod:`rigmap.rigs.blender.retarget`): Blender
  solves the constraints once per frame, one rig evaluation each;
- any other rig is refused.

Rig evaluations are counted by calling the rig (or the counting wrapper the
evaluation runner passes) through ``world_transforms`` / ``constraint_retarget``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rigmap.errors import RigmapError
from rigmap.retarget.scene import ScriptScene
from rigmap.rigs.base import Pose, RigInputError, check_placement, check_positions
from rigmap.rigs.manifest import all_manifests

Script = Callable[[ScriptScene, np.ndarray, np.ndarray], None]

# frames per batch: bounds the memory of the rig's read-backs (every named transform)
DEFAULT_CHUNK = 2048
# how far a COG rotation may be from orthonormal before it is refused
_ROTATION_TOLERANCE = 1e-4


class NoRetargetScriptError(RigmapError, LookupError):
    """The rig has no hand-written retarget script."""


@dataclass(frozen=True)
class ScriptResult:
    """Values of the rig's used controls ``(N, C_used)`` and what the script cost."""

    Y_used: np.ndarray
    rig_evaluations: int  # poses the rig evaluated (read-backs, plus one rest pose per batch)


def script_retarget(rig, positions, cog=None, cog_rotation=None, *, chunk: int = DEFAULT_CHUNK):
    """Run the rig's retarget script on ``(N, J, 3)`` COG-relative targets (cm).

    ``cog`` ``(N, 3)`` and ``cog_rotation`` ``(N, 3, 3)`` are the COG's world
    placement; a :class:`~rigmap.rigs.base.Pose` may be passed as ``positions``
    instead of all three. Returns a :class:`ScriptResult`.
    """
    script = script_for(rig.name)
    if script is None and not _has_constraint_retarget(rig):
        raise NoRetargetScriptError(
            f"no retarget script for rig {rig.name!r}; scripts exist for "
            f"{', '.join(scripted_rigs())} and for Blender rigs with a 'retarget' mapping "
            "in their config (constraint-based, rigmap.rigs.blender.retarget)"
        )
    if isinstance(positions, Pose):
        positions, cog, cog_rotation = positions
    where = f"script_retarget on rig {rig.name!r}"
    X = check_positions(positions, rig.n_joints, where)
    cog, cog_rotation = _check_placement(cog, cog_rotation, len(X), where)
    if script is None:
        # one constraint solve per frame; a counting wrapper records them
        Y = np.asarray(rig.constraint_retarget(X, cog, cog_rotation), dtype=np.float64)
        return ScriptResult(Y[:, rig.controls.used_indices], len(X))
    if chunk < 1:
        raise ValueError(f"{where}: chunk must be a positive number of frames, got {chunk}")
    world = X + cog[:, None, :]
    used = rig.controls.used_indices
    parts, evaluations = [], 0
    for start in range(0, len(X), chunk):
        frames = slice(start, start + chunk)
        scene = ScriptScene(rig, world[frames])
        script(scene, cog[frames], cog_rotation[frames])
        parts.append(scene.controls[:, used])
        evaluations += scene.evaluations
    Y_used = np.concatenate(parts) if parts else np.zeros((0, len(used)))
    return ScriptResult(Y_used, evaluations)


def scripted_rigs() -> list[str]:
    """Rigs whose manifest names a hand-written retarget script."""
    return sorted(name for name, m in all_manifests().items() if m.script is not None)


def script_for(rig_name: str) -> Script | None:
    """The hand-written script a rig's manifest names, or ``None``."""
    known = all_manifests().get(rig_name)
    return None if known is None else known.script_function()


def _has_constraint_retarget(rig) -> bool:
    """A Blender rig that knows which controls follow which joints (its ``retarget`` list)."""
    return callable(getattr(rig, "constraint_retarget", None)) and bool(
        getattr(rig, "retarget_mapping", None)
    )


def _check_placement(cog, cog_rotation, n: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """The COG placement, its rotations proper rotation matrices (the script reads frames)."""
    cog, cog_rotation = check_placement(cog, cog_rotation, n, where)
    drift = np.abs(np.swapaxes(cog_rotation, -1, -2) @ cog_rotation - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero((drift > _ROTATION_TOLERANCE) | (np.linalg.det(cog_rotation) <= 0))
    if bad.size:
        raise RigInputError(
            f"{where}: cog_rotation must be rotation matrices (orthonormal, det +1); "
            f"frame {bad[0]} is not (|RᵀR − I| = {drift[bad[0]]:.3g})"
        )
    return cog, cog_rotation
