"""The errors of paper §6.1 and the result of one method on a rig's test clips.

The two errors — *joint error* (cm², the visual error) and *ground-truth
error* (controls in training-std units, the naturalness error) — are defined
in :mod:`rigmap.error_measures`, which the fit's training error shares; they
are re-exported here.

A ``MethodResult`` gathers per-clip results, averages them over all test
frames (each frame weighs the same, so ``fps`` = frames / seconds), and writes
the metrics JSON and the per-frame CSV atomically.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rigmap.error_measures import (  # noqa: F401  re-exported: evaluation code imports them here
    CONSTANT_STD,
    FrameErrors,
    GroundTruthError,
    MetricInputError,
    control_std,
    ground_truth_error,
    joint_error,
    joint_rms,
)
from rigmap.error_measures import finite_array as _finite_array
from rigmap.evaluation.novelty import NOVELTY_MEASURE, rank_correlation
from rigmap.store import json_ready, write_text_atomic

RESULT_FORMAT = "rigmap.method_result/1"

#: what each metric measures, written next to the numbers in the metrics JSON
METRIC_UNITS = {
    "joint_error": "{unit}^2, mean over frames and the 3J joint coordinates",
    "ground_truth_error": "dimensionless: controls divided by their training-corpus std",
    "total_time_s": "s, wall clock (time.perf_counter), warm-up excluded",
    "fps": "frames per second = frames / total_time_s",
    "rig_evaluations": "poses the rig evaluated (finite-difference perturbations included)",
    "rig_calls": "calls to the rig (each evaluates a batch of poses)",
    "joint_rms": "{unit}, root mean squared joint distance = sqrt(3 x joint_error)",
    "joint_rms_percent_of_height": "% of the character's rest height (scale-free)",
    "novelty_error_spearman": "Spearman's rank correlation of per-frame novelty and joint error",
}


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
    novelty_per_frame: np.ndarray | None = None  # rigmap.evaluation.novelty; None: not measured

    def __post_init__(self) -> None:
        where = f"clip {self.clip!r}"
        if self.novelty_per_frame is not None:
            novelty = _finite_array(self.novelty_per_frame, f"{where}: novelty_per_frame")
            if novelty.shape != np.shape(self.joint_error_per_frame) or (novelty < 0).any():
                raise MetricInputError(
                    f"{where}: expected one novelty >= 0 per frame "
                    f"({np.shape(self.joint_error_per_frame)}), got shape {novelty.shape}"
                )
            self.novelty_per_frame = novelty
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
        return _with_confidence(_summary(self), [self])


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
    character_height: float | None = None  # rest height (length unit); None: not measured

    def __post_init__(self) -> None:
        if self.character_height is not None and not self.character_height > 0:
            raise MetricInputError(
                f"{self.method} on rig {self.rig!r}: character_height must be > 0, "
                f"got {self.character_height!r}"
            )
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
        return _with_confidence(self._scale_free(_summary(self)), self.clips)

    def _scale_free(self, numbers: dict[str, float | int]) -> dict[str, float | int]:
        """``numbers`` plus the joint error as an RMS distance, and as % of the height."""
        rms = joint_rms(float(numbers["joint_error"]))
        numbers = {**numbers, "joint_rms": rms}
        if self.character_height is not None:
            numbers["joint_rms_percent_of_height"] = 100.0 * rms / self.character_height
        return numbers

    # --- files --------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The metrics JSON as a dict: averages, per-clip numbers, units and timing rules."""
        return {
            "format": RESULT_FORMAT,
            "rig": self.rig,
            "method": self.method,
            "sampler": self.sampler,
            "length_unit": self.length_unit,
            "character_height": self.character_height,
            "average": self.average(),
            "clips": {c.clip: self._scale_free(c.summary()) for c in self.clips},
            "confidence": _confidence_record(self.clips),
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
        """One row per test frame: ``clip``, ``frame``, ``joint_error``, ``ground_truth_error``
        and, when measured, ``novelty`` (the per-frame confidence)."""
        columns = {
            "clip": np.concatenate([[c.clip] * c.frames for c in self.clips]),
            "frame": np.concatenate([c.frame_numbers for c in self.clips]),
            "joint_error": np.concatenate([c.joint_error_per_frame for c in self.clips]),
            "ground_truth_error": np.concatenate(
                [c.ground_truth_error_per_frame for c in self.clips]
            ),
        }
        if _has_novelty(self.clips):
            columns["novelty"] = np.concatenate([c.novelty_per_frame for c in self.clips])
        return pd.DataFrame(columns)


SUMMARY_FIELDS = (
    "frames",
    "joint_error",
    "ground_truth_error",
    "total_time_s",
    "fps",
    "rig_evaluations",
    "rig_calls",
)


def _summary(result) -> dict[str, float | int]:
    """A clip's or a method's numbers, in the metrics files' order."""
    return {name: getattr(result, name) for name in SUMMARY_FIELDS}


def _has_novelty(clips) -> bool:
    return all(c.novelty_per_frame is not None for c in clips)


def _novelty_correlation(clips) -> float | None:
    """Spearman's ρ of novelty and joint error over the clips' frames (None: not measured)."""
    if not _has_novelty(clips):
        return None
    return rank_correlation(
        np.concatenate([c.novelty_per_frame for c in clips]),
        np.concatenate([c.joint_error_per_frame for c in clips]),
    )


def _with_confidence(numbers: dict[str, float | int], clips) -> dict[str, float | int]:
    """``numbers`` plus the novelty/error rank correlation, when it was measured."""
    rho = _novelty_correlation(clips)
    return numbers if rho is None else {**numbers, "novelty_error_spearman": rho}


def _confidence_record(clips) -> dict[str, Any] | None:
    """What the per-frame ``novelty`` column of the CSV is, and how well it ranks the errors."""
    if not _has_novelty(clips):
        return None
    return {
        "per_frame_column": "novelty",
        "measure": NOVELTY_MEASURE,
        "novelty_error_spearman": _novelty_correlation(clips),
    }


def write_per_frame_csv(result: MethodResult, path: str | os.PathLike) -> Path:
    """Write the per-frame errors as CSV (a DVC plot: x = frame, y = the errors), atomically."""
    return write_text_atomic(path, result.per_frame_table().to_csv(index=False))


#: the old name, still imported by rigmap.reports.index_page and
#: rigmap.reports.table; new code calls rigmap.store.write_text_atomic
write_text_atomically = write_text_atomic
