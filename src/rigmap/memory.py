"""Refuse, before allocating, a request that needs more memory than the machine has free.

A count option (``budget.samples``, ``map.frames`` …) sizes arrays; a large enough value
makes the process die in an allocation (or swap for hours) far into a run. Callers
estimate the bytes a value needs and call :func:`check_memory` before the first array of
that size exists; the error names the option, the value, the estimate and what is free.
"""

from __future__ import annotations

import psutil

from rigmap.errors import RigmapError


class MemoryBudgetError(RigmapError, ValueError):
    """An option's value would need more memory than the machine has available."""


def available_bytes() -> int:
    """Memory the machine can give this process now (psutil's ``available``: free plus
    reclaimable caches, without swapping)."""
    return int(psutil.virtual_memory().available)


def check_memory(need: float, option: str, value, what: str) -> None:
    """``MemoryBudgetError`` when ``need`` bytes (``what``, for ``option=value``) exceed the
    available memory."""
    free = available_bytes()
    if need > free:
        raise MemoryBudgetError(
            f"{option}={value}: {what} need about {_gib(need)} of memory, more than the "
            f"{_gib(free)} available; lower {option}"
        )


def _gib(n: float) -> str:
    return f"{n / 2**30:.1f} GiB"
