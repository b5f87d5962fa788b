"""Moving a motion between rigs: one rig's keyed curves written onto another rig's controls.

What a TD does with a mapping table when two rigs share a character (the dog and
Rigify's wolf, the biped and Rigify's human): the motion is keyed on a stand-in
builder that speaks the source rig's control names (:func:`key_through_stand_in`),
then a :class:`CurveRekeyer` keys each target control on the frames its source
controls are keyed on, with their interpolation. Target controls the source has no
counterpart for get a small seeded settle (:class:`SettleChannel`). The libraries
that do this (:mod:`.wolf`, :mod:`.rigify_human`) hold the mapping tables.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np

from rigmap.animation.keyframes import FCurve
from rigmap.animation.library import Motion, MotionLibrary
from rigmap.animation.library.clip_builder import ClipBuilder


def rest_value(name: str, table: Mapping[str, float]) -> float:
    """A control's rest value from a table keyed by channel name (``ik_fk``); 0 otherwise."""
    return table.get(name.rsplit(".", 1)[1], 0.0)


@dataclass(frozen=True)
class Term:
    """``weight`` × (source control − its rest value)."""

    source: str
    weight: float


@dataclass(frozen=True)
class SettleChannel:
    """A target control the source has no counterpart for: seeded values around ``centre``."""

    target: str
    centre: float
    spread: float
    lower: float = -math.inf
    upper: float = math.inf


class CurveRekeyer:
    """Reads a source motion's nominal curves and writes target keys onto a clip builder.

    ``source_defaults`` holds the source controls whose rest value is not 0 (by channel).
    """

    source_defaults: Mapping[str, float] = {}

    def __init__(self, curves: Mapping[str, FCurve]):
        self.curves = dict(curves)

    def _frames(self, sources: Iterable[str]) -> np.ndarray:
        """The frames any of ``sources`` is keyed on (empty when none is animated)."""
        present = [self.curves[s].frames for s in sources if s in self.curves]
        if not present:
            return np.zeros(0)
        return np.unique(np.concatenate(present))

    def _value(self, source: str, frames: np.ndarray) -> np.ndarray:
        """The source control's offset from its rest value at ``frames``."""
        curve = self.curves.get(source)
        if curve is None:
            return np.zeros(len(frames))
        values = np.asarray(curve.evaluate(frames), dtype=np.float64)
        return values - rest_value(source, self.source_defaults)

    def _interpolation(self, sources: Iterable[str], frame: float) -> str:
        """The interpolation the source keys on this frame share; Bézier when they differ."""
        kinds = {
            key.interpolation
            for s in sources
            if s in self.curves
            for key in self.curves[s].keys
            if key.frame == frame
        }
        return kinds.pop() if len(kinds) == 1 else "bezier"

    def _write(self, b: ClipBuilder, target: str, sources, frames, values) -> None:
        for frame, value in zip(frames, values, strict=True):
            b.key(target, float(frame), float(value), self._interpolation(sources, frame))

    def _settle(self, b: ClipBuilder, channels: Sequence[SettleChannel]) -> None:
        """Seeded values on the clip's first, middle and last keyed frame (a carriage pass)."""
        frames = b.nominal_frames
        picks = sorted({frames[0], frames[len(frames) // 2], frames[-1]})
        for channel in channels:
            for frame in picks:
                value = b.vary(channel.centre, channel.spread)
                b.key(channel.target, float(frame), min(max(value, channel.lower), channel.upper))


def key_through_stand_in(
    design: Callable[[ClipBuilder], None],
    rekeyer: Callable[[Mapping[str, FCurve]], CurveRekeyer],
    b: ClipBuilder,
) -> None:
    """Key the source motion ``design`` on a stand-in builder, then re-key it onto ``b``.

    The stand-in draws from ``b``'s generator, so the take is the target clip's own.
    """
    stand_in = ClipBuilder(b.name, b.rng, variation=b.variation, description=b.description)
    design(stand_in)
    rekeyer(stand_in.nominal_curves()).key_onto(b)


def library_through_stand_in(
    rig: str,
    source: MotionLibrary,
    rekeyer: Callable[[Mapping[str, FCurve]], CurveRekeyer],
) -> MotionLibrary:
    """``source``'s motions, same names and splits, each keyed through its stand-in rig
    and re-keyed onto ``rig`` by ``rekeyer`` (:func:`key_through_stand_in`)."""

    def on_rig(motion: Motion) -> Motion:
        keyframe = partial(key_through_stand_in, motion.keyframe, rekeyer)
        return Motion(motion.name, keyframe, motion.description)

    return MotionLibrary(
        rig=rig,
        train=tuple(on_rig(m) for m in source.train),
        test=tuple(on_rig(m) for m in source.test),
    )
