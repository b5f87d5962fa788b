"""How well a propagated edit matches the edit applied to the held-out clip (rigmap's own
measures: the paper judged its results by eye, §7.2).

Per clip, with ``s`` the source, ``g`` the ground truth (the procedural edit applied to
the source) and ``ŷ`` the propagated result, all in training-std units:

- ``edit_error_std``: mean of ``(ŷ − g)²`` over frames and channels (the project's
  ground-truth error); ``source_error_std`` the same for copying the source;
- ``joint_rmse_cm``: RMS distance of the joints relative to the root (world-oriented),
  ``ŷ`` against ``g``; ``source_joint_rmse_cm`` for the source; ``root_drift_cm``: mean
  ground distance between ``ŷ``'s and ``g``'s integrated root paths;
- ``transfer``: ``Σ⟨ŷ − s, g − s⟩ / Σ‖g − s‖²`` (ρ: 1 the whole edit, 0 the source);
- ``leak_std`` / ``leak_cm``: RMS of ``ŷ − s`` on frames the edit leaves alone (no channel
  moved by more than ``leak_threshold`` std);
- ``jerk_ratio``: mean squared third difference of ``ŷ`` over that of ``g``;
- ``drift_std``: RMS of the one-second moving average of ``ŷ − g`` (slow offsets, what
  integrating accelerations alone accumulates).

Sums are kept (:class:`Tally`) so clips pool frame-weighted; the thresholds are ours.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import uniform_filter1d

from rigmap.edits.representation import ChannelScale, TargetTrack

LEAK_THRESHOLD_STD = 0.01  # ours
DRIFT_WINDOW_S = 1.0  # ours


@dataclass
class Tally:
    """Sums over frames of every measure, so clips pool into one number each."""

    sums: dict[str, float] = field(default_factory=dict)

    def add(self, **values: float) -> None:
        for key, value in values.items():
            self.sums[key] = self.sums.get(key, 0.0) + float(value)

    def merge(self, other: Tally) -> None:
        self.add(**other.sums)

    def summary(self) -> dict[str, float]:
        s = self.sums
        ratio = _ratio
        return {
            "edit_error_std": ratio(s, "sq_error", "cells"),
            "source_error_std": ratio(s, "sq_source", "cells"),
            "joint_rmse_cm": np.sqrt(ratio(s, "sq_joint", "joint_cells")),
            "source_joint_rmse_cm": np.sqrt(ratio(s, "sq_joint_source", "joint_cells")),
            "root_drift_cm": ratio(s, "root_distance", "frames"),
            "transfer": ratio(s, "inner", "edit_norm"),
            "leak_std": np.sqrt(ratio(s, "sq_leak", "leak_cells")),
            "leak_cm": np.sqrt(ratio(s, "sq_leak_joint", "leak_joint_cells")),
            "leak_frames": s.get("leak_frames", 0.0),
            "jerk_ratio": ratio(s, "jerk", "jerk_truth"),
            "drift_std": np.sqrt(ratio(s, "sq_drift", "cells")),
            "frames": s.get("frames", 0.0),
        }


def score_clip(
    source: TargetTrack,
    truth: TargetTrack,
    result: TargetTrack,
    scale: ChannelScale,
    relative_cm,
    leak_threshold: float = LEAK_THRESHOLD_STD,
) -> Tally:
    """The sums of one clip (see the module docstring); ``relative_cm(track)`` gives
    root-relative joint positions in cm (``None``: no joint measures, no rig evaluation)."""
    s, g, y = (scale.scaled(t) for t in (source, truth, result))
    if relative_cm is None:
        ps = pg = py = np.zeros((len(s), 0, 3))
    else:
        ps, pg, py = (relative_cm(t) for t in (source, truth, result))
    n, d = s.shape
    joints = ps.shape[1]
    alone = np.abs(g - s).max(axis=1) <= leak_threshold
    root_g, root_y = truth.root(), result.root()
    drift = uniform_filter1d(
        y - g, size=max(1, round(DRIFT_WINDOW_S * source.fps)), axis=0, mode="nearest"
    )
    third = np.diff(y, n=3, axis=0)
    third_truth = np.diff(g, n=3, axis=0)
    tally = Tally()
    tally.add(
        sq_error=((y - g) ** 2).sum(),
        sq_source=((s - g) ** 2).sum(),
        cells=n * d,
        sq_joint=((py - pg) ** 2).sum(),
        sq_joint_source=((ps - pg) ** 2).sum(),
        joint_cells=n * joints,
        frames=n,
        root_distance=np.hypot(root_y.x - root_g.x, root_y.z - root_g.z).sum(),
        inner=((y - s) * (g - s)).sum(),
        edit_norm=((g - s) ** 2).sum(),
        sq_leak=((y - s)[alone] ** 2).sum(),
        leak_cells=alone.sum() * d,
        sq_leak_joint=((py - ps)[alone] ** 2).sum(),
        leak_joint_cells=alone.sum() * joints,
        leak_frames=alone.sum(),
        jerk=(third**2).sum(),
        jerk_truth=(third_truth**2).sum(),
        sq_drift=(drift**2).sum(),
    )
    return tally


def edit_fraction(
    source: TargetTrack, other: TargetTrack, full: TargetTrack, scale: ChannelScale
) -> np.ndarray:
    """Per frame, how much of the full edit ``other`` carries: ``⟨o − s, e − s⟩ / ‖e − s‖²``
    with ``e`` the edit at full strength (NaN where the full edit is zero)."""
    s, o, e = (scale.scaled(t) for t in (source, other, full))
    norm = ((e - s) ** 2).sum(axis=1)
    inner = ((o - s) * (e - s)).sum(axis=1)
    return np.where(norm > 1e-12, inner / np.where(norm > 1e-12, norm, 1.0), np.nan)


def _ratio(sums: dict[str, float], top: str, bottom: str) -> float:
    below = sums.get(bottom, 0.0)
    return float(sums.get(top, 0.0) / below) if below > 0 else float("nan")
