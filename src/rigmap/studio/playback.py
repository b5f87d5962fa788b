"""A clip's frames played on a thread of their own, by the clock (the Review and Edit views).

Frames are counted from an anchor ``(frame, time)`` at the clip's rate, so a slow page or a
busy machine skips frames instead of slowing the clip down; a scrub during playback moves
the anchor. Each new frame number is handed to the view's ``tick``.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

TICK_S = 0.005  # how often (s) the thread looks at the clock; ours


class FrameClock:
    """``play(first, n_frames, fps, tick, loop=, ended=)``: ``tick(frame)`` for every new
    frame; past the last, ``loop()`` true wraps around, else playback stops and ``ended()``
    is called."""

    def __init__(self, name: str):
        self._wake = threading.Condition()
        self._playing = False
        self._stopped = False
        self._anchor = (0, 0.0)  # (frame, monotonic time) playback counts from
        self._clip: tuple = (1, 24.0, None, None, None)  # n_frames, fps, tick, loop, ended
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    @property
    def playing(self) -> bool:
        return self._playing

    def play(
        self,
        first: int,
        n_frames: int,
        fps: float,
        tick: Callable[[int], None],
        *,
        loop: Callable[[], bool] = lambda: True,
        ended: Callable[[], None] = lambda: None,
    ) -> None:
        with self._wake:
            self._anchor = (int(first), time.monotonic())
            self._clip = (int(n_frames), float(fps), tick, loop, ended)
            self._playing = True
            self._wake.notify()

    def rewind(self, frame: int) -> None:
        """Count on from ``frame``, now (a scrub while playing)."""
        with self._wake:
            self._anchor = (int(frame), time.monotonic())

    def pause(self) -> bool:
        """Stop playing; whether it was."""
        with self._wake:
            was, self._playing = self._playing, False
        return was

    def close(self) -> None:
        with self._wake:
            self._stopped = True
            self._wake.notify()

    def _run(self) -> None:
        last = None
        while True:
            with self._wake:
                while not self._playing and not self._stopped:
                    self._wake.wait()
                    last = None
                if self._stopped:
                    return
                (first, started), (n, fps, tick, loop, ended) = self._anchor, self._clip
            frame = first + int((time.monotonic() - started) * fps)
            if frame >= n and not loop():
                if self.pause():
                    ended()
                continue
            frame %= n
            if frame != last:
                last = frame
                tick(frame)
            time.sleep(TICK_S)


class PlaysFrames:
    """A view with a :class:`FrameClock` in ``_clock`` and its own ``play``/``pause``:
    the Play/Pause button's toggle."""

    _clock: FrameClock

    @property
    def playing(self) -> bool:
        return self._clock.playing

    def toggle(self) -> None:
        if self._clock.playing:
            self.pause()
        else:
            self.play()
