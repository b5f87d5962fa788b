"""The two errors of paper §6.1, shared by the fit (training error) and the evaluation.

*Joint error* is the visual error: the mean squared difference between the
joint positions the method's controls produce and the target positions. It is
the mean over frames and over the ``3J`` coordinates of ``x`` (the paper's
joint vector, §3.2), in the rig's length unit squared — the same per-frame
number refinement minimises. Multiply by 3 for the mean squared joint distance.

*Ground-truth error* is the naturalness error: the mean squared difference
between the method's controls and the animator's, each control divided by its
standard deviation in the training corpus (rotations in radians before
scaling), so rotations, translations and custom attributes weigh alike.

A control whose training standard deviation is (nearly) zero has no scale: the
animators never moved it in the training clips. Dividing by a tiny number would
let one such control swamp every other, and any floor would be an arbitrary
unit. Such controls are left out of the mean and reported instead — how many,
which, and the largest raw difference seen on them — so nothing is hidden.

This module sits below both ``rigmap.regression`` and ``rigmap.evaluation``
(which re-exports it from ``rigmap.evaluation.metrics``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigmap.errors import RigmapError
from rigmap.rigs.base import CONTROL_KINDS

#: training standard deviation at or below which a control counts as constant (its own units)
CONSTANT_STD = 1e-9


class MetricInputError(RigmapError, ValueError):
    """Predictions and targets that cannot be compared: wrong shapes or non-finite values."""


# --------------------------------------------------------------------------- joint error
@dataclass(frozen=True)
class FrameErrors:
    """An error per frame and its mean over frames."""

    per_frame: np.ndarray

    @property
    def mean(self) -> float:
        return float(self.per_frame.mean())


def joint_error(X_pred: Any, X_target: Any) -> FrameErrors:
    """Mean squared joint-position error per frame, in the rig's length unit squared.

    Both inputs are ``(N, J, 3)`` or flat ``(N, 3J)`` (they may differ in layout).
    """
    pred = _flat_positions(X_pred, "joint_error: X_pred")
    target = _flat_positions(X_target, "joint_error: X_target")
    if pred.shape != target.shape:
        raise MetricInputError(
            f"joint_error: X_pred has {pred.shape[0]} frames x {pred.shape[1]} coordinates but "
            f"X_target has {target.shape[0]} x {target.shape[1]}; expected the same shape"
        )
    return FrameErrors(((pred - target) ** 2).mean(axis=1))


def joint_rms(mean_squared_coordinate_error: float) -> float:
    """The joint error as a distance: the root mean squared joint distance, in the rig's
    length unit. The joint error averages over the 3 coordinates of each joint, so the mean
    squared distance is 3 x it; a reader compares centimetres, not centimetres squared."""
    if not mean_squared_coordinate_error >= 0:
        raise MetricInputError(
            f"joint_rms: expected a mean squared error >= 0, got {mean_squared_coordinate_error!r}"
        )
    return float(np.sqrt(3.0 * mean_squared_coordinate_error))


def _flat_positions(X: Any, where: str) -> np.ndarray:
    X = finite_array(X, where)
    if X.ndim == 3 and X.shape[2] == 3:
        X = X.reshape(X.shape[0], -1)
    elif not (X.ndim == 2 and X.shape[1] % 3 == 0):
        raise MetricInputError(
            f"{where}: expected joint positions of shape (N, J, 3) or (N, 3J), got {X.shape}"
        )
    if X.shape[0] == 0 or X.shape[1] == 0:
        raise MetricInputError(f"{where}: expected at least one frame and one joint, got {X.shape}")
    return X


# --------------------------------------------------------------------------- ground truth
def control_std(Y_train: Any) -> np.ndarray:
    """Per-control standard deviation of the training corpus ``(N, C)`` (population, ddof 0)."""
    Y = finite_array(Y_train, "control_std: Y_train")
    if Y.ndim != 2 or Y.shape[0] < 2:
        raise MetricInputError(
            f"control_std: expected training controls of shape (N >= 2, C), got {Y.shape}"
        )
    return Y.std(axis=0)


@dataclass(frozen=True)
class GroundTruthError:
    """Std-normalised control error per frame, its split by control kind, and what was skipped.

    ``per_kind`` maps each kind present among the scored controls to its mean
    normalised squared error. ``skipped`` names the controls left out for a
    constant training value; ``skipped_max_abs_difference`` is the largest raw
    difference on them (their own units; 0.0 when none were skipped or all agree).
    """

    per_frame: np.ndarray
    per_kind: dict[str, float]
    scored_controls: int
    skipped: tuple[str, ...]
    skipped_max_abs_difference: float

    @property
    def mean(self) -> float:
        return float(self.per_frame.mean())


def ground_truth_error(
    Y_pred: Any,
    Y_true: Any,
    train_std: Any,
    kinds: Sequence[str],
    *,
    names: Sequence[str] | None = None,
    constant_std: float = CONSTANT_STD,
) -> GroundTruthError:
    """Mean squared control error per frame, each control divided by its training std.

    ``Y_pred``/``Y_true``: ``(N, C)`` controls (rotations in radians);
    ``train_std``: ``(C,)`` from ``control_std`` on the training corpus;
    ``kinds``: the ``C`` control kinds. Controls with ``train_std <= constant_std``
    are skipped and reported (see the module docstring); ``names`` labels them.
    """
    pred = finite_array(Y_pred, "ground_truth_error: Y_pred")
    true = finite_array(Y_true, "ground_truth_error: Y_true")
    if pred.ndim != 2 or pred.shape != true.shape or pred.shape[0] == 0:
        raise MetricInputError(
            "ground_truth_error: expected Y_pred and Y_true of the same shape (N >= 1, C), "
            f"got {pred.shape} and {true.shape}"
        )
    n_controls = pred.shape[1]
    std = finite_array(train_std, "ground_truth_error: train_std")
    if std.shape != (n_controls,) or (std < 0).any():
        raise MetricInputError(
            f"ground_truth_error: expected train_std of shape ({n_controls},) with values >= 0, "
            f"got shape {std.shape}"
            + (f" with minimum {std.min():g}" if std.size and std.ndim == 1 else "")
        )
    kinds = [str(k) for k in kinds]
    if len(kinds) != n_controls:
        raise MetricInputError(
            f"ground_truth_error: expected {n_controls} control kinds, got {len(kinds)}"
        )
    unknown = sorted(set(kinds) - set(CONTROL_KINDS))
    if unknown:
        raise MetricInputError(
            f"ground_truth_error: unknown control kinds {unknown}; expected {CONTROL_KINDS}"
        )
    if names is None:
        names = [f"control[{i}]" for i in range(n_controls)]
    elif len(names) != n_controls:
        raise MetricInputError(
            f"ground_truth_error: expected {n_controls} control names, got {len(names)}"
        )
    if not constant_std >= 0:
        raise MetricInputError(f"ground_truth_error: constant_std must be >= 0, got {constant_std}")

    scored = std > constant_std
    if not scored.any():
        raise MetricInputError(
            f"ground_truth_error: all {n_controls} controls have a training std <= "
            f"{constant_std:g}; there is no scale to normalise by (is the training corpus static?)"
        )
    normalised = ((pred[:, scored] - true[:, scored]) / std[scored]) ** 2
    scored_kinds = np.asarray(kinds)[scored]
    per_kind = {
        kind: float(normalised[:, scored_kinds == kind].mean())
        for kind in CONTROL_KINDS
        if (scored_kinds == kind).any()
    }
    skipped = ~scored
    largest_skipped = 0.0
    if skipped.any():
        largest_skipped = float(np.abs(pred[:, skipped] - true[:, skipped]).max())
    return GroundTruthError(
        per_frame=normalised.mean(axis=1),
        per_kind=per_kind,
        scored_controls=int(scored.sum()),
        skipped=tuple(str(names[i]) for i in np.flatnonzero(skipped)),
        skipped_max_abs_difference=largest_skipped,
    )


def finite_array(values: Any, where: str) -> np.ndarray:
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise MetricInputError(
            f"{where}: expected numbers, got {type(values).__name__} ({error})"
        ) from None
    if not np.isfinite(array).all():
        first = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        raise MetricInputError(f"{where}: contains NaN or infinity (first at index {first})")
    return array
