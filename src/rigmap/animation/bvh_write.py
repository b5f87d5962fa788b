"""Writing a :class:`rigmap.animation.bvh.BVHMotion` back to a BVH file (rotations kept).

Written here because no maintained Python BVH writer is a dependency of rigmap (the
reader, :mod:`rigmap.animation.bvh`, is rigmap's own too), and the edit commands must hand
an artist a file their DCC opens with the source's own hierarchy and channel orders.
:func:`rigmap.map.bvh_export.write_joint_bvh` writes positions only (no rotations), which
loses the joints' twist; this keeps every joint's channels as the source listed them.
Joints are written depth first in index order (the reader's order), a joint's end sites
before its child joints; channel values with 6 decimals (degrees and the file's length
unit: ours, finer than the CMU files' 4–6).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from rigmap.animation.bvh import CHANNEL_NAMES, BVHError, BVHMotion
from rigmap.store import write_text_atomic


def bvh_text(motion: BVHMotion) -> str:
    """The BVH file of ``motion`` as text (checked: one root first, finite values)."""
    parents = [int(p) for p in motion.parents]
    if not parents or parents[0] != -1 or parents.count(-1) != 1:
        raise BVHError(f"{motion.source}: a BVH needs one root joint, listed first")
    if any(not 0 <= p < j for j, p in enumerate(parents[1:], start=1)):
        raise BVHError(f"{motion.source}: every joint's parent must come before it")
    bad = sorted({c for joint in motion.channels for c in joint} - set(CHANNEL_NAMES))
    if bad:
        raise BVHError(f"{motion.source}: unknown channels {bad}")
    values = np.asarray(motion.values, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != motion.channel_count or len(values) == 0:
        raise BVHError(
            f"{motion.source}: values {values.shape} for {motion.channel_count} channels"
        )
    if not np.isfinite(values).all():
        frame = int(np.argwhere(~np.isfinite(values))[0, 0])
        raise BVHError(f"{motion.source}: a channel value is not finite at frame {frame}")
    lines = ["HIERARCHY"]
    _joint_lines(lines, motion, 0, 0)
    lines += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {motion.frame_time:.9g}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in values]
    return "\n".join(lines) + "\n"


def write_bvh(motion: BVHMotion, path: str | os.PathLike) -> Path:
    """Write ``motion`` to ``path`` atomically (nothing left half-written); returns it."""
    return write_text_atomic(path, bvh_text(motion))


def _offset(vector) -> str:
    return "OFFSET " + " ".join(f"{float(v):.9g}" for v in vector)


def _joint_lines(lines: list[str], motion: BVHMotion, j: int, depth: int) -> None:
    pad = "\t" * depth
    kind = "ROOT" if depth == 0 else "JOINT"
    channels = motion.channels[j]
    lines += [
        f"{pad}{kind} {motion.joint_names[j]}",
        f"{pad}{{",
        f"{pad}\t{_offset(motion.offsets[j])}",
        f"{pad}\tCHANNELS {len(channels)} {' '.join(channels)}".rstrip(),
    ]
    for e in np.flatnonzero(np.asarray(motion.end_site_parents) == j):
        lines += [
            f"{pad}\tEnd Site",
            f"{pad}\t{{",
            f"{pad}\t\t{_offset(motion.end_site_offsets[e])}",
            f"{pad}\t}}",
        ]
    for child in np.flatnonzero(np.asarray(motion.parents) == j):
        _joint_lines(lines, motion, int(child), depth + 1)
    lines.append(f"{pad}}}")
