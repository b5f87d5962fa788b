"""Where refinement's Jacobians come from: the rig itself, or a model learned from it (§4.3-4.4).

A source is called with the current full controls of the frames still
moving, their COG-relative targets, and their indices in the refined batch
(``frames``), so a source that holds per-frame data — a learned Jacobian's
input features — picks its rows directly. It returns ``(F, 3J, C_used)``
Jacobians and the rig evaluations they cost.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from rigmap.refine.jacobian import DIFFERENCES, jacobian
from rigmap.rigs.base import Rig


class JacobianSource(Protocol):
    """Gives ``(F, 3J, C_used)`` Jacobians and says how many rig evaluations that cost."""

    #: True when the Jacobian depends on the current controls (recomputed each iteration)
    per_iteration: bool

    def __call__(
        self, Y_full: np.ndarray, X_target: np.ndarray, frames: np.ndarray | None = None
    ) -> tuple[np.ndarray, int]: ...


@dataclass
class ComputedJacobian:
    """The rig's own Jacobian at the current controls (finite differences or autodiff).

    ``differences`` ``"central"`` costs two rig evaluations per used control
    and pose, ``"forward"`` one (plus the pose itself) at an error of the
    order of the step (1e-6 in float64, far below a cm). A rig in another
    process (a DCC's worker pool) gets every perturbation of every frame in
    one ``evaluate`` call, so its workers run at their batch rate.
    """

    rig: Rig
    method: str = "finite_difference"
    differences: str = "central"
    step: float | None = None  # finite-difference step in control units (None: jacobian's)
    per_iteration: bool = True

    def __post_init__(self) -> None:
        if self.differences not in DIFFERENCES:
            raise ValueError(
                f"ComputedJacobian: differences must be one of {DIFFERENCES}, "
                f"got {self.differences!r}"
            )

    def cost_per_pose(self) -> int:
        """Rig evaluations one pose's Jacobian costs (autodiff: one differentiable pass)."""
        if self.method != "finite_difference":
            return 1
        n_used = len(self.rig.controls.used_indices)
        return 2 * n_used if self.differences == "central" else n_used + 1

    def __call__(
        self, Y_full: np.ndarray, X_target: np.ndarray, frames: np.ndarray | None = None
    ) -> tuple[np.ndarray, int]:
        # in-process rigs: about 1 750 perturbed poses per call (larger batches ran at half the
        # pose rate on the quadruped); a worker pool: everything in one call
        chunk = 8 if getattr(self.rig, "differentiable", False) else None
        J = jacobian(
            self.rig,
            Y_full,
            method=self.method,
            differences=self.differences,
            chunk=chunk,
            step=self.step,
        )
        return J, len(Y_full) * self.cost_per_pose()


@dataclass
class PredictedJacobian:
    """A learned Jacobian predicted once at the target pose (Algorithm 1, line 9).

    ``model.predict(inputs)`` must return ``(N, 3J, C_used)`` (or flattened).
    With ``features`` (``(N, D)``, the inputs the model was trained on, one row
    per refined frame — e.g. ``inverse_features`` of the targets) every
    frame's Jacobian is predicted on the first call and later calls pick
    their ``frames``; without, the model reads the flattened COG-relative
    targets it is given.
    """

    model: Any
    features: np.ndarray | None = None
    per_iteration: bool = False
    _predicted: np.ndarray | None = field(default=None, init=False, repr=False)

    def __call__(
        self, Y_full: np.ndarray, X_target: np.ndarray, frames: np.ndarray | None = None
    ) -> tuple[np.ndarray, int]:
        rows = X_target[0].size
        if self.features is None:
            n = len(X_target)
            J = np.asarray(self.model.predict(X_target.reshape(n, -1)), dtype=np.float64)
            return J.reshape(n, rows, -1), 0
        if self._predicted is None:
            features = np.asarray(self.features)
            J = np.asarray(self.model.predict(features), dtype=np.float64)
            self._predicted = J.reshape(len(features), rows, -1)
        if frames is None:
            if len(X_target) != len(self._predicted):
                raise ValueError(
                    f"PredictedJacobian: {len(X_target)} targets but features for "
                    f"{len(self._predicted)} frames; pass the frames' indices"
                )
            return self._predicted, 0
        return self._predicted[np.asarray(frames)], 0
