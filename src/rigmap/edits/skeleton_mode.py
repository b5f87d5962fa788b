"""Skeleton mode (§4.5): a BVH clip as joint rotations relative to the parent, as exp maps.

"We encode the skeletal configuration as joint angles parameterized by exponential maps
[Grassia 1998] … We encode the orientation of each bone relative to the orientation of
its parent" (§4.5). Every non-root joint gives three channels ``<joint>.x/.y/.z`` (its
local rotation's rotation vector, radians); the root gives its height ``root.height``
and its tilt (its rotation with the heading removed, ``root.tilt.x/.y/.z``), its ground
position and heading going to the differential root channels of
:mod:`rigmap.edits.representation`. Rotation vectors are made continuous over time: of
the two vectors of a rotation (``v`` and ``v − 2π v̂``), each frame keeps the one closer
to the previous frame's, so no channel jumps by 2π.

:func:`skeleton_positions` is the inverse: forward kinematics of a track on the clip's
skeleton (offsets from the BVH), in the BVH's length unit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from rigmap.animation.bvh import POSITION_CHANNELS, ROTATION_CHANNELS, BVHMotion
from rigmap.edits.representation import (
    ROOT_CHANNELS,
    TargetError,
    TargetTrack,
    root_differentials,
)
from rigmap.regression.placement import heading, turn_matrix

AXES = ("x", "y", "z")


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Joint names, parents (root first) and rest offsets of a BVH skeleton."""

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray

    @classmethod
    def of(cls, motion: BVHMotion) -> Skeleton:
        if int(np.sum(motion.parents < 0)) != 1 or motion.parents[0] != -1:
            raise TargetError(f"{motion.source}: skeleton mode needs one root, listed first")
        return cls(motion.joint_names, motion.parents.copy(), motion.offsets.copy())

    def check_same(self, other: Skeleton, where: str) -> None:
        if self.joint_names != other.joint_names or not np.array_equal(self.parents, other.parents):
            missing = sorted(set(self.joint_names) ^ set(other.joint_names))[:5]
            raise TargetError(
                f"{where}: a different skeleton ({len(other.joint_names)} joints "
                f"vs {len(self.joint_names)}; joints that differ: {missing})"
            )

    def channels(self) -> tuple[str, ...]:
        pose = ["root.height", *(f"root.tilt.{a}" for a in AXES)]
        pose += [f"{name}.{a}" for name in self.joint_names[1:] for a in AXES]
        return (*ROOT_CHANNELS, *pose)


def local_rotations(motion: BVHMotion) -> np.ndarray:
    """``(N, J, 3, 3)`` each joint's rotation relative to its parent, from its own channels."""
    n = motion.n_frames
    out = np.broadcast_to(np.eye(3), (n, motion.n_joints, 3, 3)).copy()
    for j, columns in enumerate(motion.channel_slices()):
        names = motion.channels[j]
        order = "".join(c[0] for c in names if c not in POSITION_CHANNELS)
        if order:
            angles = motion.values[:, columns][
                :, [k for k, c in enumerate(names) if c not in POSITION_CHANNELS]
            ]
            out[:, j] = Rotation.from_euler(order.upper(), angles, degrees=True).as_matrix()
    return out


def continuous_rotvecs(rotations: np.ndarray) -> np.ndarray:
    """``(N, K, 3, 3)`` → ``(N, K, 3)`` rotation vectors without 2π jumps between frames."""
    n, k = rotations.shape[:2]
    vectors = Rotation.from_matrix(rotations.reshape(-1, 3, 3)).as_rotvec().reshape(n, k, 3)
    angle = np.linalg.norm(vectors, axis=2, keepdims=True)
    unit = np.divide(vectors, angle, out=np.zeros_like(vectors), where=angle > 1e-9)
    other = vectors - 2.0 * np.pi * unit
    for f in range(1, n):
        flip = np.linalg.norm(other[f] - vectors[f - 1], axis=1) < np.linalg.norm(
            vectors[f] - vectors[f - 1], axis=1
        )
        vectors[f, flip] = other[f, flip]
        # the alternative of the kept vector, for the next frame's comparison
        angle_f = np.linalg.norm(vectors[f], axis=1, keepdims=True)
        unit_f = np.divide(vectors[f], angle_f, out=np.zeros_like(vectors[f]), where=angle_f > 1e-9)
        other[f] = vectors[f] - 2.0 * np.pi * unit_f
    return vectors


def skeleton_targets(motion: BVHMotion) -> TargetTrack:
    """The §4.5 target track of a BVH clip (see the module docstring)."""
    Skeleton.of(motion)
    rotations = local_rotations(motion)
    root_columns = motion.channel_slices()[0]
    root_values = motion.values[:, root_columns]
    position = motion.offsets[0] + np.column_stack(
        [
            root_values[:, motion.channels[0].index(c)]
            if c in motion.channels[0]
            else np.zeros(motion.n_frames)
            for c in POSITION_CHANNELS
        ]
    )
    root_heading = np.unwrap(heading(rotations[:, 0]))
    tilt = np.einsum("nba,nbc->nac", turn_matrix(root_heading), rotations[:, 0])
    vectors = continuous_rotvecs(np.concatenate([tilt[:, None], rotations[:, 1:]], axis=1))
    differentials = root_differentials(position[:, 0], position[:, 2], root_heading, motion.fps)
    values = np.column_stack([differentials, position[:, 1], vectors.reshape(motion.n_frames, -1)])
    start = (float(position[0, 0]), float(position[0, 2]), float(root_heading[0]))
    return TargetTrack(Skeleton.of(motion).channels(), values, motion.fps, start, motion.source)


def skeleton_positions(track: TargetTrack, skeleton: Skeleton) -> np.ndarray:
    """World joint positions ``(F, J, 3)`` of a track, by forward kinematics (BVH units)."""
    if track.channels != skeleton.channels():
        raise TargetError(f"{track.source}: its channels are not this skeleton's")
    local = track_rotations(track, len(skeleton.joint_names))
    return forward_kinematics(track, skeleton, local)[1]


def track_rotations(track: TargetTrack, k: int) -> np.ndarray:
    """``(F, K, 3, 3)`` the local rotations a track's rotation vectors hold (the root's
    tilt, without its heading)."""
    n = track.n_frames
    vectors = track.values[:, 5:].reshape(n, k, 3)
    return Rotation.from_rotvec(vectors.reshape(-1, 3)).as_matrix().reshape(n, k, 3, 3)


def forward_kinematics(
    track: TargetTrack, skeleton: Skeleton, local: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World rotations ``(F, J, 3, 3)`` and positions ``(F, J, 3)`` of ``local`` rotations
    on the track's root path (heading, ground position, height): one FK for the
    positions and the procedural edits."""
    n, k = local.shape[:2]
    root = track.root()
    world_r = np.empty_like(local)
    world_p = np.empty((n, k, 3))
    world_r[:, 0] = turn_matrix(root.heading) @ local[:, 0]
    world_p[:, 0] = np.column_stack([root.x, track.values[:, 4], root.z])
    for j in range(1, k):
        p = skeleton.parents[j]
        world_r[:, j] = world_r[:, p] @ local[:, j]
        world_p[:, j] = world_p[:, p] + world_r[:, p] @ skeleton.offsets[j]
    return world_r, world_p


def track_motion(track: TargetTrack, template: BVHMotion) -> BVHMotion:
    """The inverse of :func:`skeleton_targets`: ``track`` as BVH channel values of
    ``template``'s hierarchy (its joints, offsets and per-joint channel orders), at the
    track's frame rate, so :mod:`rigmap.animation.bvh_write` can write it. Euler angles are
    unwrapped over time (a whole turn added to one angle changes no rotation); position
    channels of non-root joints are written 0, as skeleton mode reads none."""
    skeleton = Skeleton.of(template)
    if track.channels != skeleton.channels():
        raise TargetError(f"{track.source}: its channels are not {template.source}'s skeleton's")
    n, k = track.n_frames, len(skeleton.joint_names)
    root = track.root()
    local = track_rotations(track, k)
    local[:, 0] = turn_matrix(root.heading) @ local[:, 0]
    position = np.column_stack([root.x, track.values[:, 4], root.z]) - template.offsets[0]
    values = np.zeros((n, template.channel_count))
    for j, columns in enumerate(template.channel_slices()):
        names = template.channels[j]
        rotation = [c for c in names if c in ROTATION_CHANNELS]
        if len(rotation) not in (0, 3):
            raise TargetError(
                f"{template.source}: joint {template.joint_names[j]!r} has "
                f"{len(rotation)} rotation channels; writing needs 0 or 3"
            )
        angles = None
        if rotation:
            order = "".join(c[0] for c in rotation).upper()
            angles = Rotation.from_matrix(local[:, j]).as_euler(order, degrees=True)
            angles = np.unwrap(angles, period=360.0, axis=0)
        for offset, name in enumerate(names):
            column = columns.start + offset
            if name in POSITION_CHANNELS:
                if j == 0:
                    values[:, column] = position[:, POSITION_CHANNELS.index(name)]
            else:
                values[:, column] = angles[:, rotation.index(name)]
    source = f"{track.source} (BVH)"
    return replace(template, values=values, frame_time=1.0 / track.fps, source=source)
