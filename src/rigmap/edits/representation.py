"""The target representation of §4.5: per frame, Δt, the root's step and turn, the pose.

"We represent target frames using an estimate of skeletal configuration, but require
also an estimate of the time elapsed since the last frame, the ground-plane translation,
and the vertical rotation of the root relative to the root at the last frame" (§4.5).
A :class:`TargetTrack` holds exactly that: the first four channels are ``dt`` (seconds),
``root.step_forward`` and ``root.step_lateral`` (the root's ground-plane move since the
last frame, in the last frame's heading frame, length units) and ``root.turn`` (its
heading change, radians); the pose channels follow (exponential maps in skeleton mode,
:mod:`rigmap.edits.skeleton_mode`; rig controls in rig mode, :mod:`rigmap.edits.rig_mode`).
Frame 0 has no previous frame: its differentials repeat frame 1's (so the second
difference the acceleration predictor sees has no spike there), and the track keeps the
root's starting placement to integrate from.

Headings follow :func:`rigmap.regression.placement.turn_matrix`: heading ``h`` faces
``(sin h, 0, cos h)``. :class:`ChannelScale` divides every channel by its training
standard deviation (the "training-std units" the GPs and errors work in).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rigmap.errors import RigmapError

ROOT_CHANNELS = ("dt", "root.step_forward", "root.step_lateral", "root.turn")
#: a channel whose training std is below this fraction of the median channel's counts as
#: constant (ours: below every moving channel of the built-in biped, 6 % at the least; far
#: above the CMU hinges' rounding noise, 2e-4 %)
NEAR_CONSTANT_FRACTION = 0.01


class TargetError(RigmapError, ValueError):
    """A clip that cannot become (or come back from) a target track; names what and where."""


@dataclass(frozen=True)
class RootPlacement:
    """The root's ground position ``x``, ``z`` and heading per frame, and the frame times."""

    x: np.ndarray
    z: np.ndarray
    heading: np.ndarray
    time: np.ndarray


@dataclass(frozen=True, eq=False)
class TargetTrack:
    """``values (F, D)`` on ``channels`` (the four root channels first), at ``fps``.

    ``start`` is the root's ``(x, z, heading)`` on frame 0; ``source`` names the clip.
    """

    channels: tuple[str, ...]
    values: np.ndarray
    fps: float
    start: tuple[float, float, float]
    source: str = "<clip>"

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.float64)
        if self.channels[:4] != ROOT_CHANNELS:
            raise TargetError(f"{self.source}: a target track starts with {ROOT_CHANNELS}")
        if values.ndim != 2 or values.shape[1] != len(self.channels) or len(values) < 3:
            raise TargetError(
                f"{self.source}: values must be (F >= 3, {len(self.channels)}), got {values.shape}"
            )
        if not np.isfinite(values).all():
            frame, column = np.argwhere(~np.isfinite(values))[0]
            raise TargetError(
                f"{self.source}: channel {self.channels[column]!r} is not finite at frame {frame}"
            )
        object.__setattr__(self, "values", values)

    @property
    def n_frames(self) -> int:
        return len(self.values)

    @property
    def pose_channels(self) -> tuple[str, ...]:
        return self.channels[4:]

    def column(self, channel: str) -> int:
        try:
            return self.channels.index(channel)
        except ValueError:
            raise TargetError(f"{self.source}: no channel {channel!r}") from None

    def with_values(self, values: np.ndarray, source: str | None = None) -> TargetTrack:
        return replace(
            self, values=np.asarray(values, dtype=np.float64), source=source or self.source
        )

    def frames(self, start: int, stop: int) -> TargetTrack:
        """Frames ``start:stop``, starting from the root placement integrated to ``start``."""
        if not 0 <= start < stop <= self.n_frames or stop - start < 3:
            raise TargetError(
                f"{self.source}: frames {start}:{stop} are not a range of at "
                f"least 3 of its {self.n_frames} frames"
            )
        root = self.root()
        first = (float(root.x[start]), float(root.z[start]), float(root.heading[start]))
        return replace(
            self,
            values=self.values[start:stop].copy(),
            start=first,
            source=f"{self.source}[{start}:{stop}]",
        )

    def root(self) -> RootPlacement:
        """The root's placement, integrated from ``start`` (§4.5's "integrating the
        differential estimates of elapsed time and root transformation")."""
        return integrate_root(self.values[:, :4], self.start)


def root_differentials(x, z, heading, fps: float) -> np.ndarray:
    """``(F, 4)``: ``dt``, the step in the previous frame's heading frame, the turn."""
    x, z, heading = (np.asarray(a, dtype=np.float64) for a in (x, z, heading))
    dx, dz = np.diff(x), np.diff(z)
    s, c = np.sin(heading[:-1]), np.cos(heading[:-1])
    forward = dx * s + dz * c
    lateral = dx * c - dz * s
    turn = _wrap(np.diff(heading))
    rows = np.column_stack([np.full(len(dx), 1.0 / fps), forward, lateral, turn])
    return np.vstack([rows[:1], rows])


def integrate_root(differentials: np.ndarray, start) -> RootPlacement:
    """The inverse of :func:`root_differentials` (frame 0's row is not integrated)."""
    d = np.asarray(differentials, dtype=np.float64)
    heading = start[2] + np.concatenate([[0.0], np.cumsum(d[1:, 3])])
    s, c = np.sin(heading[:-1]), np.cos(heading[:-1])
    dx = d[1:, 1] * s + d[1:, 2] * c
    dz = d[1:, 1] * c - d[1:, 2] * s
    x = start[0] + np.concatenate([[0.0], np.cumsum(dx)])
    z = start[1] + np.concatenate([[0.0], np.cumsum(dz)])
    time = np.concatenate([[0.0], np.cumsum(d[1:, 0])])
    return RootPlacement(x, z, heading, time)


def resample(values: np.ndarray, time: np.ndarray, fps: float) -> np.ndarray:
    """Rows at ``time`` (seconds, increasing) onto the fixed schedule ``0, 1/fps, …`` (§4.5:
    "the target sequence must then be resampled"); linear interpolation, ours."""
    time = np.asarray(time, dtype=np.float64)
    if np.any(np.diff(time) <= 0):
        raise TargetError("the integrated frame times do not increase: a predicted dt <= 0")
    grid = np.arange(0.0, time[-1] + 0.5 / fps, 1.0 / fps)
    return np.column_stack([np.interp(grid, time, column) for column in values.T])


@dataclass(frozen=True)
class ChannelScale:
    """Per-channel training standard deviation; a channel (nearly) constant in training keeps
    its own unit, scale 1 (ours: it has no spread to measure in).

    Nearly constant: below :data:`NEAR_CONSTANT_FRACTION` of the median channel's std. A
    BVH hinge joint's two unused axes are rounding noise in training (the CMU knees' and
    elbows' exponential maps: std 5e-7 rad); divided by that, an edit that turns one (bowed
    legs) measured 6e6 "std units" and dominated the GP's shared hyper-parameters.
    """

    channels: tuple[str, ...]
    std: np.ndarray

    @classmethod
    def fit(cls, tracks: list[TargetTrack]) -> ChannelScale:
        channels = tracks[0].channels
        for track in tracks[1:]:
            if track.channels != channels:
                raise TargetError(f"{track.source}: channels differ from {tracks[0].source}'s")
        std = np.concatenate([t.values for t in tracks]).std(axis=0)
        varying = std > 1e-12
        if varying.any():
            varying &= std >= NEAR_CONSTANT_FRACTION * float(np.median(std[varying]))
        return cls(channels, np.where(varying, std, 1.0))

    def scaled(self, track: TargetTrack) -> np.ndarray:
        self.check(track)
        return track.values / self.std

    def unscaled(self, values: np.ndarray) -> np.ndarray:
        return np.asarray(values, dtype=np.float64) * self.std

    def check(self, track: TargetTrack) -> None:
        if track.channels != self.channels:
            extra = sorted(set(track.channels) ^ set(self.channels))[:5]
            raise TargetError(
                f"{track.source}: its channels are not the training channels "
                f"({len(track.channels)} vs {len(self.channels)}; differ: {extra})"
            )


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi
