"""The errors of paper §6.1 and the result of one method on a rig's test clips.

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

A ``MethodResult`` gathers per-clip results, averages them over all test
frames (each frame weighs the same, so ``fps`` = frames / seconds), and writes
the metrics JSON and the per-frame CSV atomically.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rigmap.errors import RigmapError
from rigmap.rigs.base import CONTROL_KINDS
from rigmap.store import json_ready, write_text_atomic

RESULT_FORMAT = "rigmap.method_result/1"

#: training standard deviation at or below which a control counts as constant (its own units)
CONSTANT_STD = 1e-9

#: what each metric measures, written next to the numbers in the metrics JSON
METRIC_UNITS = {
    "joint_error": "{unit}^2, mean over frames and the 3J joint coordinates",
    "ground_truth_error": "dimensionless: controls divided by their training-corpus std",
    "total_time_s": "s, wall clock (time.perf_counter), warm-up excluded",
    "fps": "frames per second = frames / total_time_s",
    "rig_evaluations": "poses the rig evaluated (finite-difference perturbations included)",
    "rig_calls": "calls to the rig (each evaluates a batch of poses)",
}


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


def _flat_positions(X: Any, where: str) -> np.ndarray:
    X = _finite_array(X, where)
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
    Y = _finite_array(Y_train, "control_std: Y_train")
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
    pred = _finite_array(Y_pred, "ground_truth_error: Y_pred")
    true = _finite_array(Y_true, "ground_truth_error: Y_true")
    if pred.ndim != 2 or pred.shape != true.shape or pred.shape[0] == 0:
        raise MetricInputError(
            "ground_truth_error: expected Y_pred and Y_true of the same shape (N >= 1, C), "
            f"got {pred.shape} and {true.shape}"
        )
    n_controls = pred.shape[1]
    std = _finite_array(train_std, "ground_truth_error: train_std")
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


# --------------------------------------------------------------------------- results
@dataclass
class ClipResult:
    """One method on one test clip: per-frame errors, time and rig use.

    ``total_time_s`` is wall-clock seconds for the whole clip (warm-up
    excluded); ``rig_evaluations`` counts poses, ``rig_calls`` calls.
    ``frame_numbers`` are the clip's own frame numbers (default ``0..N-1``).
    """

    clip: str
    joint_error_per_frame: np.ndarray
    ground_truth_error_per_frame: np.ndarray
    total_time_s: float
    rig_evaluations: int = 0
    rig_calls: int = 0
    frame_numbers: np.ndarray | None = None

    def __post_init__(self) -> None:
        where = f"clip {self.clip!r}"
        self.joint_error_per_frame = _finite_array(
            self.joint_error_per_frame, f"{where}: joint_error_per_frame"
        )
        self.ground_truth_error_per_frame = _finite_array(
            self.ground_truth_error_per_frame, f"{where}: ground_truth_error_per_frame"
        )
        n = len(self.joint_error_per_frame)
        if self.joint_error_per_frame.ndim != 1 or n == 0:
            raise MetricInputError(
                f"{where}: expected a non-empty 1-D joint_error_per_frame, "
                f"got shape {self.joint_error_per_frame.shape}"
            )
        if self.ground_truth_error_per_frame.shape != (n,):
            raise MetricInputError(
                f"{where}: expected {n} ground-truth errors (one per frame), "
                f"got shape {self.ground_truth_error_per_frame.shape}"
            )
        if (self.joint_error_per_frame < 0).any() or (self.ground_truth_error_per_frame < 0).any():
            raise MetricInputError(f"{where}: squared errors cannot be negative")
        if self.frame_numbers is None:
            self.frame_numbers = np.arange(n)
        self.frame_numbers = np.asarray(self.frame_numbers)
        if self.frame_numbers.shape != (n,) or self.frame_numbers.dtype.kind not in "iu":
            raise MetricInputError(
                f"{where}: expected {n} integer frame numbers, got "
                f"{self.frame_numbers.dtype} of shape {self.frame_numbers.shape}"
            )
        if not (np.isfinite(self.total_time_s) and self.total_time_s > 0):
            raise MetricInputError(
                f"{where}: total_time_s must be a positive number of seconds, "
                f"got {self.total_time_s!r}"
            )
        for name in ("rig_evaluations", "rig_calls"):
            value = getattr(self, name)
            if int(value) != value or value < 0:
                raise MetricInputError(f"{where}: {name} must be a count >= 0, got {value!r}")
            setattr(self, name, int(value))
        self.total_time_s = float(self.total_time_s)

    @property
    def frames(self) -> int:
        return len(self.joint_error_per_frame)

    @property
    def joint_error(self) -> float:
        return float(self.joint_error_per_frame.mean())

    @property
    def ground_truth_error(self) -> float:
        return float(self.ground_truth_error_per_frame.mean())

    @property
    def fps(self) -> float:
        return self.frames / self.total_time_s

    def summary(self) -> dict[str, float | int]:
        return {
            "frames": self.frames,
            "joint_error": self.joint_error,
            "ground_truth_error": self.ground_truth_error,
            "total_time_s": self.total_time_s,
            "fps": self.fps,
            "rig_evaluations": self.rig_evaluations,
            "rig_calls": self.rig_calls,
        }


@dataclass
class MethodResult:
    """A method's results on every test clip of a rig, and their average over all frames.

    ``skipped_controls`` names controls left out of the ground-truth error for
    a constant training value; ``warmup_frames`` says how many frames ran
    untimed before timing started; ``extra`` holds JSON-able context (kernel,
    refinement settings, notes) written into the metrics JSON as it is.
    """

    rig: str
    method: str
    sampler: str
    clips: list[ClipResult]
    length_unit: str = "cm"
    warmup_frames: int = 0
    skipped_controls: tuple[str, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.clips:
            raise MetricInputError(
                f"{self.method} on rig {self.rig!r}: no clip results; expected at least one"
            )
        names = [c.clip for c in self.clips]
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise MetricInputError(f"{self.method} on rig {self.rig!r}: clips repeated: {repeated}")
        self.skipped_controls = tuple(self.skipped_controls)

    # --- averages over all test frames -----------------------------------
    @property
    def frames(self) -> int:
        return sum(c.frames for c in self.clips)

    @property
    def joint_error(self) -> float:
        return float(np.concatenate([c.joint_error_per_frame for c in self.clips]).mean())

    @property
    def ground_truth_error(self) -> float:
        return float(np.concatenate([c.ground_truth_error_per_frame for c in self.clips]).mean())

    @property
    def total_time_s(self) -> float:
        return float(sum(c.total_time_s for c in self.clips))

    @property
    def fps(self) -> float:
        return self.frames / self.total_time_s

    @property
    def rig_evaluations(self) -> int:
        return sum(c.rig_evaluations for c in self.clips)

    @property
    def rig_calls(self) -> int:
        return sum(c.rig_calls for c in self.clips)

    def average(self) -> dict[str, float | int]:
        return {
            "frames": self.frames,
            "joint_error": self.joint_error,
            "ground_truth_error": self.ground_truth_error,
            "total_time_s": self.total_time_s,
            "fps": self.fps,
            "rig_evaluations": self.rig_evaluations,
            "rig_calls": self.rig_calls,
        }

    # --- files --------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The metrics JSON as a dict: averages, per-clip numbers, units and timing rules."""
        return {
            "format": RESULT_FORMAT,
            "rig": self.rig,
            "method": self.method,
            "sampler": self.sampler,
            "length_unit": self.length_unit,
            "average": self.average(),
            "clips": {c.clip: c.summary() for c in self.clips},
            "units": {k: v.format(unit=self.length_unit) for k, v in METRIC_UNITS.items()},
            "timing": {
                "clock": "wall clock, time.perf_counter",
                "warmup_frames": int(self.warmup_frames),
                "warmup_excluded": True,
            },
            "ground_truth_error_skipped_controls": {
                "count": len(self.skipped_controls),
                "names": list(self.skipped_controls),
                "rule": "training std <= threshold: no scale to normalise by; left out",
            },
            "extra": json_ready(self.extra, nonfinite_to_null=False),
        }

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False) + "\n"

    def write_json(self, path: str | os.PathLike) -> Path:
        """Write the metrics JSON atomically."""
        return write_text_atomic(path, self.to_json())

    def per_frame_table(self) -> pd.DataFrame:
        """One row per test frame: ``clip``, ``frame``, ``joint_error``, ``ground_truth_error``."""
        return pd.DataFrame(
            {
                "clip": np.concatenate([[c.clip] * c.frames for c in self.clips]),
                "frame": np.concatenate([c.frame_numbers for c in self.clips]),
                "joint_error": np.concatenate([c.joint_error_per_frame for c in self.clips]),
                "ground_truth_error": np.concatenate(
                    [c.ground_truth_error_per_frame for c in self.clips]
                ),
            }
        )


def write_per_frame_csv(result: MethodResult, path: str | os.PathLike) -> Path:
    """Write the per-frame errors as CSV (a DVC plot: x = frame, y = the errors), atomically."""
    return write_text_atomic(path, result.per_frame_table().to_csv(index=False))


#: the old name, still imported by rigmap.tracking.runs, rigmap.reports.index_page and
#: rigmap.reports.table; new code calls rigmap.store.write_text_atomic
write_text_atomically = write_text_atomic


# --------------------------------------------------------------------------- helpers
def _finite_array(values: Any, where: str) -> np.ndarray:
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
