"""Rig mode (issue 17, item 2): a clip as the rig's used controls, root channels as steps.

The built-in rigs have no joint rotations to edit, but their used controls are what an
animator keys; a target track's pose channels are those controls (their own units; the
GPs see them divided by the training std, :class:`rigmap.edits.representation.ChannelScale`)
except the root's ground translations and turn, which become the per-frame step and turn
of :mod:`rigmap.edits.representation` (so where the clip stands and faces does not
matter). The root channels are named by the caller (``root.tx``, ``root.tz``,
``root.ry`` on the biped: ``ry`` turns about +Y, translations in cm, one unit = one
world cm / radian — what :func:`rigmap.regression.placement.find_placement` finds), each
with a sign taking it to rigmap's Y-up ground plane and turn about +Y, the axes every
rig's ``rig.pose`` returns: a Z-up Blender rig's ``root.tx``, ``root.ty``, ``root.rz``
are x, -z and the turn (rigmap's z is Blender's -y; a turn about Blender's +Z is one
about rigmap's +Y, the map between the two being a proper rotation), signs (1, -1, 1).

The source joint positions the features need are the rig's own (``rig.pose``: positions
relative to the COG plus the COG's world position).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rigmap.edits.representation import ROOT_CHANNELS, TargetError, TargetTrack, root_differentials


@dataclass(frozen=True)
class RigChannels:
    """The used controls of a rig, which three of them place the root (x, z, turn) and the
    sign (±1) taking each to rigmap's x, z and turn about +Y (module docstring)."""

    used: tuple[str, ...]
    root: tuple[str, str, str] = ("root.tx", "root.tz", "root.ry")
    signs: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        missing = [name for name in self.root if name not in self.used]
        if missing:
            raise TargetError(
                f"root channels {missing} are not among the rig's {len(self.used)} used controls"
            )
        if len(self.signs) != 3 or any(s not in (1.0, -1.0) for s in self.signs):
            raise TargetError(f"root channel signs must be three of +1 or -1, got {self.signs}")

    @property
    def root_columns(self) -> list[int]:
        return [self.used.index(name) for name in self.root]

    @property
    def pose(self) -> tuple[str, ...]:
        return tuple(name for name in self.used if name not in self.root)

    def channels(self) -> tuple[str, ...]:
        return (*ROOT_CHANNELS, *self.pose)


def rig_targets(
    controls: np.ndarray, channels: RigChannels, fps: float, source: str = "<clip>"
) -> TargetTrack:
    """``(F, U)`` used controls (columns in ``channels.used`` order) → a target track."""
    controls = np.asarray(controls, dtype=np.float64)
    if controls.ndim != 2 or controls.shape[1] != len(channels.used):
        raise TargetError(
            f"{source}: controls must be (F, {len(channels.used)}) in the used "
            f"controls' order, got {controls.shape}"
        )
    x, z, turn = (
        sign * controls[:, c] for c, sign in zip(channels.root_columns, channels.signs, strict=True)
    )
    differentials = root_differentials(x, z, turn, fps)
    pose_columns = [channels.used.index(name) for name in channels.pose]
    values = np.column_stack([differentials, controls[:, pose_columns]])
    start = (float(x[0]), float(z[0]), float(turn[0]))
    return TargetTrack(channels.channels(), values, fps, start, source)


def rig_controls(track: TargetTrack, channels: RigChannels) -> np.ndarray:
    """The inverse of :func:`rig_targets`: ``(F, U)`` used controls, root integrated."""
    if track.channels != channels.channels():
        raise TargetError(f"{track.source}: its channels are not this rig's used controls")
    root = track.root()
    out = np.empty((track.n_frames, len(channels.used)))
    placed = (root.x, root.z, root.heading)
    for column, sign, values in zip(channels.root_columns, channels.signs, placed, strict=True):
        out[:, column] = sign * values
    for k, name in enumerate(channels.pose):
        out[:, channels.used.index(name)] = track.values[:, 4 + k]
    return out


def full_controls(
    used_values: np.ndarray, used_indices: Sequence[int], defaults: np.ndarray
) -> np.ndarray:
    """``(F, C)`` all controls: the used ones given, the rest at their defaults (§6.1)."""
    out = np.tile(np.asarray(defaults, dtype=np.float64), (len(used_values), 1))
    out[:, list(used_indices)] = used_values
    return out
