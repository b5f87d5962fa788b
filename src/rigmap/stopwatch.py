"""A wall-clock stopwatch over laps, for any package that times its own work.

Here, beside no package, so regression (a fit's phases) and evaluation (Table 1's
timings, which re-exports it from :mod:`rigmap.evaluation.timing`) share one clock
without regression importing evaluation (a package cycle, ``tests/test_import_graph.py``).
"""

from __future__ import annotations

import time


class Stopwatch:
    """Wall-clock seconds accumulated over start/stop laps (``time.perf_counter``).

    Use as a context manager for one lap: ``with Stopwatch() as watch: ...``,
    then read ``watch.elapsed``.
    """

    def __init__(self) -> None:
        self.elapsed = 0.0
        self.laps = 0
        self._started: float | None = None

    @property
    def running(self) -> bool:
        return self._started is not None

    def start(self) -> Stopwatch:
        if self._started is not None:
            raise RuntimeError("Stopwatch.start: already running; stop() it first")
        self._started = time.perf_counter()
        return self

    def stop(self) -> float:
        """End the current lap; return its seconds."""
        if self._started is None:
            raise RuntimeError("Stopwatch.stop: not running; start() it first")
        lap = time.perf_counter() - self._started
        self._started = None
        self.elapsed += lap
        self.laps += 1
        return lap

    def __enter__(self) -> Stopwatch:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
