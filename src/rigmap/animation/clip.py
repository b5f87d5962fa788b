"""A clip: one named piece of keyframed animation on some of a rig's controls.

A clip knows its frame rate and frame range but not the rig: a control without a
curve holds the rig's default, which the caller passes in when the clip is
evaluated. Keys may sit on fractional frames (after a retime); the clip is
sampled on whole frames, as a DCC plays it back.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from rigmap.animation.keyframes import FCurve, KeyframeError, KeyLike

CLIP_FPS: tuple[int, ...] = (24, 30)


class Clip:
    """Curves on controls, a frame rate (24 or 30 fps) and an inclusive frame range.

    ``curves`` maps a control name to an ``FCurve`` or to its keys (``Key`` objects
    or ``(frame, value)`` pairs). ``start``/``end`` default to the whole frames that
    cover every key.
    """

    def __init__(
        self,
        name: str,
        fps: int,
        curves: Mapping[str, FCurve | Iterable[KeyLike]],
        start: int | None = None,
        end: int | None = None,
        description: str = "",
    ):
        if not isinstance(name, str) or not name.strip():
            raise KeyframeError(f"a clip needs a non-empty name, got {name!r}")
        self.name = name
        self.description = description
        if fps not in CLIP_FPS or isinstance(fps, bool):
            raise KeyframeError(f"fps must be one of {CLIP_FPS}, got {fps!r}", clip=name)
        self.fps = int(fps)
        if not curves:
            raise KeyframeError("the clip has no curves; an empty clip animates nothing", clip=name)
        self.curves: dict[str, FCurve] = {}
        for control, curve in curves.items():
            if not isinstance(control, str) or not control:
                raise KeyframeError(f"control names must be non-empty strings, got {control!r}")
            try:
                if isinstance(curve, FCurve):
                    if curve.control not in (None, control):
                        raise KeyframeError(
                            f"the curve given for it is labelled {curve.control!r}",
                            control=control,
                        )
                    self.curves[control] = curve
                else:
                    self.curves[control] = FCurve(curve, control=control)
            except KeyframeError as error:
                if error.control is None:
                    error = KeyframeError(error.detail, control=control)
                raise error.in_clip(name) from None
        first = min(c.first_frame for c in self.curves.values())
        last = max(c.last_frame for c in self.curves.values())
        self.start = math.floor(first) if start is None else _whole_frame(start, "start", name)
        self.end = math.ceil(last) if end is None else _whole_frame(end, "end", name)
        if self.end < self.start:
            raise KeyframeError(
                f"frame range {self.start}..{self.end} is empty (end before start)", clip=name
            )

    # --- sizes ---------------------------------------------------------------
    def __repr__(self) -> str:
        return (
            f"Clip({self.name!r}, {self.fps} fps, frames {self.start}..{self.end}, "
            f"{len(self.curves)} curves, {self.key_count} keys)"
        )

    @property
    def controls(self) -> list[str]:
        return list(self.curves)

    @property
    def frames(self) -> np.ndarray:
        """The whole frames the clip plays, ``start..end`` inclusive."""
        return np.arange(self.start, self.end + 1, dtype=np.int64)

    @property
    def n_frames(self) -> int:
        return self.end - self.start + 1

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last frame."""
        return (self.end - self.start) / self.fps

    @property
    def key_count(self) -> int:
        """Keys over all curves (one key on one control counts one)."""
        return sum(len(c) for c in self.curves.values())

    @property
    def keyed_frames(self) -> np.ndarray:
        """The distinct frames that carry a key on at least one control (key poses)."""
        return np.unique(np.concatenate([c.frames for c in self.curves.values()]))

    # --- evaluation --------------------------------------------------------------
    def evaluate(
        self,
        control_names: Sequence[str],
        defaults: Sequence[float] | np.ndarray,
        frames: Sequence[float] | np.ndarray | None = None,
    ) -> np.ndarray:
        """``(F, C)`` values, columns in ``control_names`` order, rows at ``frames``.

        ``frames`` defaults to the clip's whole frames. Controls without a curve take
        their entry of ``defaults``. A curve on a control missing from
        ``control_names`` is an error, never silently dropped.
        """
        control_names = list(control_names)
        defaults = np.asarray(defaults, dtype=np.float64)
        if defaults.shape != (len(control_names),):
            raise ValueError(
                f"clip {self.name!r}: defaults must have one value per control, "
                f"expected shape ({len(control_names)},), got {defaults.shape}"
            )
        check_known_controls(self, control_names)
        frames = self.frames if frames is None else np.asarray(frames, dtype=np.float64)
        if frames.ndim != 1:
            raise ValueError(f"clip {self.name!r}: frames must be 1-D, got shape {frames.shape}")
        table = np.tile(defaults, (len(frames), 1))
        column = {name: i for i, name in enumerate(control_names)}
        for control, curve in self.curves.items():
            table[:, column[control]] = curve.evaluate(frames)
        return table

    def retimed(self, fps: int) -> Clip:
        """The same motion at another frame rate: keys keep their time in seconds."""
        if fps not in CLIP_FPS:
            raise KeyframeError(f"fps must be one of {CLIP_FPS}, got {fps!r}", clip=self.name)
        factor = fps / self.fps
        return Clip(
            self.name,
            fps,
            {name: curve.retimed(factor) for name, curve in self.curves.items()},
            start=round(self.start * factor),
            end=round(self.end * factor),
            description=self.description,
        )


def check_known_controls(clip: Clip, control_names: Sequence[str]) -> None:
    """Raise naming the clip and control if a curve animates a control not in the list."""
    known = set(control_names)
    for control in clip.curves:
        if control not in known:
            close = difflib.get_close_matches(control, list(control_names), n=3, cutoff=0.6)
            hint = f"; did you mean {close}?" if close else ""
            raise KeyframeError(
                f"no such control among the {len(control_names)} given{hint}",
                clip=clip.name,
                control=control,
            )


def _whole_frame(value, which: str, clip: str) -> int:
    if isinstance(value, bool) or not float(value).is_integer():
        raise KeyframeError(f"{which} frame must be a whole number, got {value!r}", clip=clip)
    return int(value)
