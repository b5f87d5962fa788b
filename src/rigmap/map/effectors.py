"""Full-body posing from a few effector targets (paper Fig. 5; FaceIK from landmarks, Fig. 10).

An animator drags a handful of effectors (hips, chest, head, hands, feet); the rig's
controls follow: the partial mapping trained on those joints gives the guess, and damped
least squares on the effectors' world positions makes it exact (:func:`solve_controls`).

Targets file (JSON): ``{"rig": "biped", "targets": {"<joint>": [x, y, z], …}}`` for one
pose, or ``"frames": [{"<joint>": [x, y, z], …}, …]`` for several; world centimetres in
the rig's axes (Y up, facing +Z).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.map.clip import MapSettings, solve_controls
from rigmap.map.partial import SubsetMapping
from rigmap.map.world_subset_rig import WorldSubsetRig
from rigmap.store import read_data_file


class EffectorError(RigmapError, ValueError):
    """An effector targets file that cannot be used; names the file and the joint."""


def read_effector_targets(path: str | os.PathLike, joints) -> np.ndarray:
    """``(N, K, 3)`` targets of ``joints`` (in that order) from a targets JSON file."""
    path = Path(path)
    data = read_data_file(path, "effector targets file", EffectorError)
    if not isinstance(data, dict) or ("targets" in data) == ("frames" in data):
        raise EffectorError(f"{path}: expected an object with 'targets' (one pose) or 'frames'")
    frames = [data["targets"]] if "targets" in data else data["frames"]
    if not isinstance(frames, list) or not frames:
        raise EffectorError(f"{path}: 'frames' must be a non-empty list of joint targets")
    out = np.empty((len(frames), len(joints), 3))
    for f, frame in enumerate(frames):
        if not isinstance(frame, dict):
            raise EffectorError(f"{path}: frame {f} is not an object of joint targets")
        missing = [j for j in joints if j not in frame]
        extra = sorted(set(frame) - set(joints))
        if missing or extra:
            raise EffectorError(
                f"{path}: frame {f}: the mapping needs targets for {list(joints)}; missing "
                f"{missing}, not used {extra}"
            )
        for k, joint in enumerate(joints):
            value = frame[joint]
            if not _is_point(value):
                raise EffectorError(f"{path}: frame {f}: {joint!r} must be [x, y, z] numbers")
            out[f, k] = value
    if not np.isfinite(out).all():
        f, k = np.argwhere(~np.isfinite(out).all(axis=2))[0]
        raise EffectorError(f"{path}: frame {f}: {joints[k]!r} is not finite")
    return out


def _is_point(value) -> bool:
    """``[x, y, z]``: three numbers (booleans are not numbers here)."""
    return (
        isinstance(value, list)
        and len(value) == 3
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    )


def pose_from_effectors(
    rig,
    mapping: SubsetMapping,
    targets: np.ndarray,
    settings: MapSettings,
    *,
    control_std: np.ndarray,
    hold_values: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, dict]:
    """Full control rows ``(N, C)`` for effector targets ``(N, K, 3)``, the per-pose RMS
    distance (cm) to the targets, and the seconds it took."""
    seconds: dict[str, float] = {}
    Y = solve_controls(
        rig,
        mapping,
        np.asarray(targets, dtype=np.float64),
        settings,
        control_std,
        hold_values,
        seconds,
    )
    controls = rig.expand_used(Y)
    reached = np.asarray(WorldSubsetRig(rig, mapping.subset.joints).evaluate(controls))
    error = np.sqrt(((reached - targets) ** 2).sum(axis=2).mean(axis=1))
    return controls, error, seconds
