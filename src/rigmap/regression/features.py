"""What the inverse mapping receives: a pose row of COG-relative joints plus the COG placement.

The paper regresses controls from joint positions relative to the centre of
gravity (§3.2). Those are blind to where the character stands, so root
controls could never be recovered from them alone; a pose row therefore also
carries the COG's world position (3 numbers, cm) and rotation (9 numbers).
The regressor itself does not see them raw: :mod:`rigmap.regression.placement`
turns a pose row into inputs that ignore where the character stands and faces
and solves the root controls from the COG placement. Refinement works on the
joint positions alone.
"""

from __future__ import annotations

import numpy as np

from rigmap.rigs.base import RigInputError, check_placement, check_positions

PLACEMENT_WIDTH = 12  # cog x, y, z + the 3x3 rotation, row-major


def inverse_features(positions, cog, cog_rotation, *, n_joints: int, where: str) -> np.ndarray:
    """``(N, 3J + 12)`` regression inputs from a pose (see :class:`rigmap.rigs.Pose`)."""
    X = check_positions(positions, n_joints, where)
    n = len(X)
    cog, cog_rotation = check_placement(cog, cog_rotation, n, where)
    return np.concatenate([X.reshape(n, -1), cog, cog_rotation.reshape(n, 9)], axis=1)


def default_pose_features(rig) -> np.ndarray:
    """``(1, 3J + 12)`` features of the rig's default pose (its default controls): the
    rest row a fit adds when no corpus frame is it, and the anchor row of tuning."""
    pose = rig.pose(rig.default_controls(1))
    return inverse_features(
        np.asarray(pose.positions),
        np.asarray(pose.cog),
        np.asarray(pose.cog_rotation),
        n_joints=rig.n_joints,
        where=f"rig {rig.name!r} default pose",
    )


def feature_names(joint_names: list[str]) -> list[str]:
    """Column names matching :func:`inverse_features` (``<joint>.x`` …, ``cog.x`` …)."""
    names = [f"{joint}.{axis}" for joint in joint_names for axis in "xyz"]
    names += [f"cog.{axis}" for axis in "xyz"]
    names += [f"cog_rot.{i}{j}" for i in range(3) for j in range(3)]
    return names


def split_features(X: np.ndarray, n_joints: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Back from features to ``(positions (N, J, 3), cog (N, 3), cog_rotation (N, 3, 3))``."""
    X = np.asarray(X, dtype=np.float64)
    width = 3 * n_joints + PLACEMENT_WIDTH
    if X.ndim != 2 or X.shape[1] != width:
        raise RigInputError(f"expected features of shape (N, {width}), got {X.shape}")
    n = len(X)
    positions = X[:, : 3 * n_joints].reshape(n, n_joints, 3)
    cog = X[:, 3 * n_joints : 3 * n_joints + 3]
    rotation = X[:, 3 * n_joints + 3 :].reshape(n, 3, 3)
    return positions, cog, rotation
