"""Fewer computed Jacobians: share them between neighbouring frames, update them by Broyden.

A finite-difference Jacobian costs one or two rig evaluations per used
control, hundreds per frame, while an iteration's step costs one. Two facts
make most of them unnecessary:

- motion is continuous, so frame ``t``'s Jacobian is a good start for frame
  ``t ± 1``: with ``share_every = k`` a clip's first Jacobians are computed on
  every k-th frame only, and each other frame starts from its nearest one;
- every step already evaluates the rig at the new controls, so the observed
  change ``Δx`` for the step ``Δy`` corrects the Jacobian for free —
  Broyden's rank-one update ``J ← J + (Δx − JΔy) Δyᵀ / ‖Δy‖²`` (Broyden 1965)
  makes ``J`` exact along the direction just travelled.

Between iterations a Jacobian is recomputed (``update="recompute"``), kept
(``"keep"``, the chord method) or corrected by Broyden (``"broyden"``); with
the last two a frame whose error stopped falling gets its own full Jacobian
at its next iteration (``recompute_on_stall``). ``share_every = 1`` with
``"recompute"`` is the original full recompute at every iteration.

``"carry"`` takes continuity further (issue #16): a clip's frames are refined
one after another, each starting from the previous frame's final Jacobian
(Broyden-updated along its steps) and from the better of its guess and the
previous refined pose moved as the guess moved; a frame gets a full Jacobian
only when a step falls well short of the decrease its Jacobian predicted
(``rigmap.refine.damped_least_squares``). On the Blender wolf, whose every
Jacobian costs a worker-pool batch, it took the rig evaluations per frame
from 310 to 35 at a lower joint error (docs/inverse-mappings.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UPDATES = ("recompute", "keep", "broyden", "carry")


@dataclass(frozen=True)
class JacobianReuse:
    """How a computed Jacobian is reused; the defaults recompute it at every iteration."""

    share_every: int = 1  # Jacobians on every k-th frame, shared with its neighbours
    update: str = "recompute"  # between iterations: recompute | keep | broyden | carry
    recompute_on_stall: bool = True  # a full Jacobian for a frame whose error stopped falling

    def __post_init__(self) -> None:
        if int(self.share_every) != self.share_every or self.share_every < 1:
            raise ValueError(
                f"jacobian reuse: share_every must be an integer >= 1, got {self.share_every!r}"
            )
        if self.update not in UPDATES:
            raise ValueError(
                f"jacobian reuse: update must be one of {UPDATES}, got {self.update!r}"
            )
        if self.update == "carry" and self.share_every != 1:
            raise ValueError(
                "jacobian reuse: update 'carry' hands each frame's Jacobian to the next "
                f"already; share_every must be 1, got {self.share_every!r}"
            )

    @property
    def recomputes_every_iteration(self) -> bool:
        return self.share_every == 1 and self.update == "recompute"


def anchor_frames(frames: np.ndarray, every: int) -> tuple[np.ndarray, np.ndarray]:
    """Every ``every``-th of ``frames`` (sorted batch indices) and, per frame, its nearest one.

    Returns ``(anchors, source)`` with ``source[i]`` the position in ``anchors``
    of the anchor nearest to ``frames[i]`` (by batch index: consecutive frames
    of a clip).
    """
    anchors = frames[::every]
    position = np.searchsorted(anchors, frames)
    below = np.clip(position - 1, 0, len(anchors) - 1)
    above = np.clip(position, 0, len(anchors) - 1)
    nearer_above = np.abs(anchors[above] - frames) <= np.abs(frames - anchors[below])
    return anchors, np.where(nearer_above, above, below)


def broyden_update(J: np.ndarray, dy: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """``J + (Δx − JΔy) Δyᵀ / ‖Δy‖²`` per frame (``(F, R, C)``, ``(F, C)``, ``(F, R)``).

    A frame that did not move (``Δy = 0``) keeps its Jacobian.
    """
    norm = np.einsum("fc,fc->f", dy, dy)
    moved = norm > 0
    miss = dx - np.einsum("frc,fc->fr", J, dy)
    weight = np.divide(1.0, norm, out=np.zeros_like(norm), where=moved)
    return J + np.einsum("fr,fc->frc", miss * weight[:, None], dy)
