"""Table 1's network rows over training seeds (issue #36): median, min–max and the count.

Float32 training follows the rounding of the CPU's code path, so a network row moves on
another host; seed 0 (``metrics/<rig>/methods/``) and each replicate seed k
(``metrics/<rig>/methods_seed<k>/``, the ``*_seed`` DVC stages) give a row's spread. A
comparison the report states between rows holds only by more than that spread.
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from rigmap.reports.metrics_tree import (  # the replicates are read with the other metrics
    NETWORK_METHODS,
    LoadedResult,
    ReportInputError,
    read_replicates,
)

__all__ = [
    "MEASURES",
    "NETWORK_METHODS",
    "Spread",
    "compare",
    "describe",
    "read_replicates",
    "row_spread",
]

MEASURES = ("joint_error", "ground_truth_error")


@dataclass(frozen=True)
class Spread:
    """A value over seeds: its median, least and greatest, and how many seeds."""

    median: float
    low: float
    high: float
    seeds: int

    @property
    def width(self) -> float:
        return self.high - self.low

    @classmethod
    def of(cls, values: Sequence[float]) -> Spread:
        if not values:
            raise ValueError("a spread needs at least one value")
        values = [float(v) for v in values]
        return cls(statistics.median(values), min(values), max(values), len(values))


def row_spread(
    seed0: LoadedResult,
    replicates: Mapping[int, Mapping[str, LoadedResult]],
    motion: str | None,
    measure: str,
) -> Spread | None:
    """``measure`` of one row (``motion`` None: the Average) over seed 0 and every replicate;
    None for a row that is not a network's or when no replicate seed was run."""
    if seed0.method not in NETWORK_METHODS or not replicates:
        return None
    results = [seed0]
    for seed, methods in replicates.items():
        if seed0.method not in methods:
            raise ReportInputError(
                f"replicate seed {seed} of rig {seed0.rig!r} has no {seed0.method!r} row "
                f"(seed 0 has one): its evaluate_seed stage did not run it"
            )
        results.append(methods[seed0.method])
    numbers = [r.average if motion is None else r.clips[motion] for r in results]
    return Spread.of([getattr(n, measure) for n in numbers])


def compare(name_a: str, a: Spread | float, name_b: str, b: Spread | float, unit: str = "") -> str:
    """``a`` against ``b`` as a sentence: below / above only by more than the larger spread
    (max - min over seeds), else "not significant"."""
    a_spread, b_spread = _as_spread(a), _as_spread(b)
    margin = max(a_spread.width, b_spread.width)
    gap = b_spread.median - a_spread.median
    if gap > margin:
        verdict = "below by more than the spread"
    elif -gap > margin:
        verdict = "above by more than the spread"
    else:
        verdict = "not significant (the difference is within the spread over seeds)"
    return (
        f"{name_a} {describe(a_spread, unit)} against {name_b} {describe(b_spread, unit)}: "
        f"{verdict}"
    )


def describe(spread: Spread, unit: str = "") -> str:
    """``4.78 cm² (4.35–5.00 over 3 seeds)``, or the value alone for one seed."""
    unit = f" {unit}" if unit else ""
    if spread.seeds == 1:
        return f"{spread.median:.3g}{unit}"
    span = f"{spread.low:.3g}–{spread.high:.3g}"
    return f"{spread.median:.3g}{unit} ({span} over {spread.seeds} seeds)"


def _as_spread(value: Spread | float) -> Spread:
    return value if isinstance(value, Spread) else Spread.of([value])
