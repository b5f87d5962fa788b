"""Honest timing of a method: wall clock, warm-up excluded, and every rig evaluation counted.

Table 1 of the paper compares total time and frames per second. On a real DCC
rig the cost is dominated by rig evaluations, so the runner wraps the rig in a
``CountingRig`` and reports how many poses (and how many calls) a method made.

The clock is ``time.perf_counter`` (wall clock, monotonic): what a user waits,
including Python overhead, BLAS threads and worker round-trips, not CPU time.
The first call of a method pays one-off costs (imports, thread pools, caches,
torch kernel selection) that a long retargeting job pays once; ``run_timed``
therefore runs the first ``warmup_frames`` frames once untimed-for-the-result,
resets the rig counter, and then times *all* frames — warm-up frames included —
in one pass. The warm-up time is reported separately, never added or hidden.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from rigmap.stopwatch import Stopwatch

Result = TypeVar("Result")
__all__ = [
    "CountingRig",
    "RigEvaluationCount",
    "ScriptCountingRig",
    "Stopwatch",
    "Timing",
    "run_timed",
]


@dataclass(frozen=True)
class RigEvaluationCount:
    """How much a method used the rig: calls made, and poses evaluated across them."""

    calls: int
    poses: int


@dataclass(frozen=True)
class Timing:
    """Seconds for ``frames`` frames, and the separately measured warm-up."""

    seconds: float
    frames: int
    warmup_seconds: float
    warmup_frames: int
    rig: RigEvaluationCount | None = None

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else float("inf")

    def to_dict(self) -> dict[str, Any]:
        out = {
            "seconds": self.seconds,
            "frames": self.frames,
            "fps": self.fps,
            "warmup_seconds": self.warmup_seconds,
            "warmup_frames": self.warmup_frames,
            "clock": "wall clock, time.perf_counter",
        }
        if self.rig is not None:
            out["rig_calls"] = self.rig.calls
            out["rig_evaluations"] = self.rig.poses
        return out


def run_timed(
    run: Callable[[Any], Result],
    frames: Any,
    *,
    warmup_frames: int = 1,
    rig: CountingRig | None = None,
    warmup: Callable[[Any], Any] | None = None,
) -> tuple[Result, Timing]:
    """``run(frames)`` timed on the wall clock after an untimed warm-up on the first frames.

    ``frames`` is anything sliceable with a length (an ``(N, ...)`` array). The
    warm-up calls ``warmup(frames[:warmup_frames])`` (``warmup`` defaults to ``run``) and
    discards the result; if ``rig`` (the ``CountingRig`` that ``run`` uses) is given, its
    counter is reset after the warm-up so the counts cover the timed pass only.
    """
    n = len(frames)
    if n == 0:
        raise ValueError("run_timed: no frames to run; expected at least one")
    if int(warmup_frames) != warmup_frames or warmup_frames < 0:
        raise ValueError(f"run_timed: warmup_frames must be an integer >= 0, got {warmup_frames!r}")
    warmup_frames = min(int(warmup_frames), n)
    stopwatch = Stopwatch()
    if warmup_frames:
        with stopwatch:
            (run if warmup is None else warmup)(frames[:warmup_frames])
    if rig is not None:
        rig.reset()
    with Stopwatch() as watch:
        result = run(frames)
    counts = rig.count if rig is not None else None
    return result, Timing(watch.elapsed, n, stopwatch.elapsed, warmup_frames, counts)


class CountingRig:
    """Wraps any rig (``evaluate``, ``pose``, ...) and counts the poses it evaluates.

    Every other attribute (``name``, ``controls``, ``n_joints``, ``expand_used``,
    ``differentiable`` ...) is delegated to the wrapped rig, so the wrapper can
    stand in for it in refinement and Jacobians. A batch ``(N, C)`` counts as
    one call and ``N`` poses; one control vector ``(C,)`` as one pose. Only
    calls that return are counted. Autodiff backward passes are not rig
    evaluations and are not counted.
    """

    def __init__(self, rig: Any):
        missing = [m for m in ("evaluate", "pose") if not callable(getattr(rig, m, None))]
        if missing:
            raise TypeError(
                f"CountingRig: expected an object with the Rig protocol (evaluate, pose); "
                f"{type(rig).__name__} has no callable {', '.join(missing)}"
            )
        self._rig = rig
        self._lock = threading.Lock()
        self._calls = 0
        self._poses = 0

    @property
    def wrapped(self) -> Any:
        return self._rig

    @property
    def count(self) -> RigEvaluationCount:
        with self._lock:
            return RigEvaluationCount(self._calls, self._poses)

    def reset(self) -> RigEvaluationCount:
        """Zero the counters; return what they held."""
        with self._lock:
            before = RigEvaluationCount(self._calls, self._poses)
            self._calls = self._poses = 0
        return before

    def evaluate(self, Y: Any) -> Any:
        out = self._rig.evaluate(Y)
        self._record(Y)
        return out

    def pose(self, Y: Any) -> Any:
        out = self._rig.pose(Y)
        self._record(Y)
        return out

    def _record(self, Y: Any) -> None:
        shape = tuple(Y.shape) if hasattr(Y, "shape") else np.shape(Y)
        poses = 1 if len(shape) <= 1 else int(shape[0])
        with self._lock:
            self._calls += 1
            self._poses += poses

    def __getattr__(self, name: str) -> Any:
        # only called for attributes not found on the wrapper itself
        if name == "_rig":  # not yet set (e.g. during copying): avoid endless recursion
            raise AttributeError(name)
        return getattr(self._rig, name)

    def __repr__(self) -> str:
        count = self.count
        return f"<CountingRig {count.calls} calls, {count.poses} poses: {self._rig!r}>"


class ScriptCountingRig(CountingRig):
    """A ``CountingRig`` that also counts a script's read-backs and Blender constraint solves."""

    def world_transforms(self, Y: Any) -> Any:
        out = self.wrapped.world_transforms(Y)
        self._record(Y)
        return out

    def constraint_retarget(self, positions: Any, cog: Any, cog_rotation: Any) -> Any:
        """A Blender rig's constraint solve: one rig evaluation per target frame."""
        out = self.wrapped.constraint_retarget(positions, cog, cog_rotation)
        self._record(positions)
        return out
