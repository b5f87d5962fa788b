"""Evaluation of inverse rig mappings (paper §6.1): errors, honest timing, and results."""

from rigmap.evaluation.metrics import (
    ClipResult,
    FrameErrors,
    GroundTruthError,
    MethodResult,
    MetricInputError,
    control_std,
    ground_truth_error,
    joint_error,
    write_per_frame_csv,
)
from rigmap.evaluation.timing import CountingRig, RigEvaluationCount, Stopwatch, Timing, run_timed

__all__ = [
    "ClipResult",
    "CountingRig",
    "FrameErrors",
    "GroundTruthError",
    "MethodResult",
    "MetricInputError",
    "RigEvaluationCount",
    "Stopwatch",
    "Timing",
    "control_std",
    "ground_truth_error",
    "joint_error",
    "run_timed",
    "write_per_frame_csv",
]
