"""Where refinement's Jacobians come from: the rig itself, or a model learned from it (§4.3-4.4).

A source is called with the current full controls of the frames still
moving, their COG-relative targets, and their indices in the refined batch
(``frames``), so a source that holds per-frame data — a learned Jacobian's
input features — picks its rows directly, and optionally the rig's positions at
the current controls (``base``: refinement has them from its residual), which
forward differences use instead of evaluating the poses again. It returns
``(F, 3J, C_used)`` Jacobians and the rig evaluations they cost.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from rigmap.refine.jacobian import DIFFERENCES, jacobian
from rigmap.refine.sparsity import rig_colouring
from rigmap.rigs.base import Rig

SPARSITIES = ("dense", "coloured")
#: perturbed poses per in-process ``evaluate`` call: 8 dense forward-difference poses (ours;
#: larger batches ran at half the pose rate on the quadruped)
POSES_PER_CALL = 1752


class JacobianSource(Protocol):
    """Gives ``(F, 3J, C_used)`` Jacobians and says how many rig evaluations that cost."""

    #: True when the Jacobian depends on the current controls (recomputed each iteration)
    per_iteration: bool

    def __call__(
        self,
        Y_full: np.ndarray,
        X_target: np.ndarray,
        frames: np.ndarray | None = None,
        base: np.ndarray | None = None,
    ) -> tuple[np.ndarray, int]: ...


@dataclass
class ComputedJacobian:
    """The rig's own Jacobian at the current controls (finite differences or autodiff).

    ``differences`` ``"central"`` costs two rig evaluations per used control
    and pose, ``"forward"`` one (plus the pose itself) at an error of the
    order of the step (1e-6 in float64, far below a cm). A rig in another
    process (a DCC's worker pool) gets every perturbation of every frame in
    one ``evaluate`` call, so its workers run at their batch rate. Given the
    positions at the current controls (``base``, refinement's residual
    evaluation), forward differences skip the pose itself: ``n`` evaluations.

    ``sparsity`` ``"coloured"`` perturbs structurally independent controls
    together (``rigmap.refine.sparsity``: the rig's pattern probed once, its
    columns coloured): on the quadruped 41 rig evaluations per forward-difference
    Jacobian instead of 218, the same Jacobian up to rounding; with autodiff one
    tangent per colour.
    """

    rig: Rig
    method: str = "finite_difference"
    differences: str = "central"
    step: float | None = None  # finite-difference step in control units (None: jacobian's)
    sparsity: str = "dense"  # dense | coloured
    per_iteration: bool = True

    def __post_init__(self) -> None:
        if self.sparsity not in SPARSITIES:
            raise ValueError(
                f"ComputedJacobian: sparsity must be one of {SPARSITIES}, got {self.sparsity!r}"
            )
        if self.differences not in DIFFERENCES:
            raise ValueError(
                f"ComputedJacobian: differences must be one of {DIFFERENCES}, "
                f"got {self.differences!r}"
            )

    def cost_per_pose(self, base_known: bool = False) -> int:
        """Rig evaluations one pose's Jacobian costs (autodiff: one differentiable pass);
        ``base_known``: the pose's own positions are given (forward differences skip it)."""
        if self.method != "finite_difference":
            return 1
        n = self.colouring().n_colours if self.sparsity == "coloured" else None
        n = len(self.rig.controls.used_indices) if n is None else n
        return 2 * n if self.differences == "central" else n + (not base_known)

    def uses_base(self) -> bool:
        """True when given positions at the current controls save rig evaluations."""
        return self.method == "finite_difference" and self.differences == "forward"

    def colouring(self):
        """The rig's column colouring (probed on first use), or None when dense."""
        return rig_colouring(self.rig) if self.sparsity == "coloured" else None

    def __call__(
        self,
        Y_full: np.ndarray,
        X_target: np.ndarray,
        frames: np.ndarray | None = None,
        base: np.ndarray | None = None,
    ) -> tuple[np.ndarray, int]:
        # in-process rigs: about POSES_PER_CALL perturbed poses per call; a worker pool:
        # everything in one call
        colouring = self.colouring()
        base = base if self.uses_base() else None
        per_pose = self.cost_per_pose(base is not None)
        in_process = getattr(self.rig, "differentiable", False)
        # a rig replaying traces says which batch size runs fastest (TorchRig.poses_per_call)
        limit = getattr(self.rig, "poses_per_call", None) or POSES_PER_CALL
        chunk = max(1, limit // per_pose) if in_process else None
        J = jacobian(
            self.rig,
            Y_full,
            method=self.method,
            differences=self.differences,
            chunk=chunk,
            step=self.step,
            colouring=colouring,
            base=base,
        )
        return J, len(Y_full) * per_pose


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
        self,
        Y_full: np.ndarray,
        X_target: np.ndarray,
        frames: np.ndarray | None = None,
        base: np.ndarray | None = None,
    ) -> tuple[np.ndarray, int]:
        rows = X_target[0].size  # base: not needed, the model never evaluates the rig
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
        frames = np.asarray(frames)
        if len(frames) == len(self._predicted) and (frames == np.arange(len(frames))).all():
            return self._predicted, 0  # every frame in order: no 30 MB copy (75 quadruped frames)
        return self._predicted[frames], 0
