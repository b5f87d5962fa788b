"""Joint positions as a BVH file, for tools that read mocap but not rig controls.

Positions, not rotations, are what a mapping reproduces, so every joint gets three
position channels and no rotation: a frame's channel values are the joint's offset from
its parent minus the rest offset. Readers that take position channels on any joint
(rigmap's own :func:`rigmap.animation.bvh.read_bvh`, Blender's importer) rebuild the
positions exactly; the hierarchy and rest offsets come from the rig's rest pose.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.store import write_text_atomic


class BVHExportError(RigmapError, ValueError):
    """Positions or a hierarchy that cannot be written as BVH."""


def write_joint_bvh(
    path: str | os.PathLike,
    joint_names,
    parents,
    positions: np.ndarray,
    rest: np.ndarray,
    fps: float,
) -> Path:
    """Write world ``positions`` ``(F, J, 3)`` (cm) of a hierarchy (``parents``, -1 = root)."""
    positions = np.asarray(positions, dtype=np.float64)
    rest = np.asarray(rest, dtype=np.float64)
    parents = [int(p) for p in parents]
    n_joints = len(joint_names)
    if positions.ndim != 3 or positions.shape[1:] != (n_joints, 3) or len(positions) == 0:
        raise BVHExportError(
            f"{path}: positions have shape {positions.shape}, expected (F > 0, {n_joints}, 3)"
        )
    if not np.isfinite(positions).all():
        raise BVHExportError(f"{path}: positions are not all finite")
    if parents.count(-1) != 1 or any(not -1 <= p < n_joints for p in parents):
        raise BVHExportError(f"{path}: parents must name one root (-1) and valid joints")
    offsets = np.array(
        [rest[j] - rest[p] if p >= 0 else np.zeros(3) for j, p in enumerate(parents)]
    )
    relative = np.stack(
        [positions[:, j] - (positions[:, p] if p >= 0 else 0.0) for j, p in enumerate(parents)],
        axis=1,
    )
    channels = relative - offsets[None]
    children = {j: [c for c, p in enumerate(parents) if p == j] for j in range(n_joints)}
    root = parents.index(-1)
    order = _hierarchy_order(children, root)
    if len(order) != n_joints:
        raise BVHExportError(f"{path}: the parents do not form one tree from {joint_names[root]!r}")
    lines = ["HIERARCHY"]
    _write_joint(lines, root, joint_names, offsets, children, depth=0)
    lines += ["MOTION", f"Frames: {len(positions)}", f"Frame Time: {1.0 / fps:.10g}"]
    flat = channels[:, order].reshape(len(positions), -1)
    lines += [" ".join(f"{v:.6f}" for v in row) for row in flat]
    return write_text_atomic(path, "\n".join(lines) + "\n")


def _write_joint(lines, j, names, offsets, children, depth) -> None:
    pad = "\t" * depth
    kind = "ROOT" if depth == 0 else "JOINT"
    lines += [
        f"{pad}{kind} {names[j]}",
        f"{pad}{{",
        f"{pad}\tOFFSET {offsets[j, 0]:.6f} {offsets[j, 1]:.6f} {offsets[j, 2]:.6f}",
        f"{pad}\tCHANNELS 3 Xposition Yposition Zposition",
    ]
    for child in children[j]:
        _write_joint(lines, child, names, offsets, children, depth + 1)
    if not children[j]:
        lines += [f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET 0 0 0", f"{pad}\t}}"]
    lines.append(f"{pad}}}")


def _hierarchy_order(children, root: int) -> list[int]:
    """Joints in the order their channels appear: depth first from the root, as written."""
    order, stack = [], [root]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(children[j]))
    return order
