"""Writing a clip the way an animator blocks a shot: key poses on a timeline, then spacing.

A motion in the library is a function that keys named controls at *nominal* frames
(the timing the motion was designed at, 24 fps). ``ClipBuilder`` collects those keys
and, when the clip is built, gives it the seeded variation that makes two takes of
the same motion differ the way two animators' takes would:

* **timing**: the whole clip plays a little faster or slower (``tempo``) and each gap
  between consecutive key poses is stretched or squeezed on its own (``timing``);
  gaps are rounded to whole frames and never shrink below one frame, so keys stay in
  order and every key pose lands on a whole frame;
* **values**: motions draw their amplitudes through :meth:`ClipBuilder.vary` and
  :meth:`ClipBuilder.factor`, whose spread the builder scales by ``values``.

The time warp is one monotone map applied to every curve, so controls keyed on the
same nominal frame stay keyed together (a key pose stays a pose) and a control held
at one value between two keys (a planted foot) stays held.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from rigmap.animation.clip import Clip
from rigmap.animation.keyframes import INTERPOLATIONS, FCurve, Interpolation, Key, KeyframeError

AUTHORED_FPS = 24


@dataclass(frozen=True)
class Variation:
    """How far a seed moves a clip away from its nominal design (fractions, 0 = none).

    ``tempo``: the whole clip's speed, ``1 ± tempo``; ``timing``: each gap between key
    poses, ``1 ± timing`` on top; ``values``: a scale on the spreads motions ask for.
    """

    tempo: float = 0.08
    timing: float = 0.15
    values: float = 1.0

    def __post_init__(self) -> None:
        for name in ("tempo", "timing", "values"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"variation {name} must be a finite number >= 0, got {value!r}")
        if self.tempo >= 1 or self.timing >= 1:
            raise ValueError(
                f"variation tempo and timing must be below 1 (they scale durations by 1 ± x), "
                f"got tempo={self.tempo}, timing={self.timing}"
            )

    def scaled(self, amount: float) -> Variation:
        """All three spreads multiplied by ``amount`` (0 gives the nominal clip)."""
        if not (np.isfinite(amount) and amount >= 0):
            raise ValueError(f"variation amount must be a finite number >= 0, got {amount!r}")
        return replace(
            self,
            tempo=self.tempo * amount,
            timing=self.timing * amount,
            values=self.values * amount,
        )


DEFAULT_VARIATION = Variation()


class ClipBuilder:
    """Collects keys at nominal frames; :meth:`build` applies the seeded timing and makes a Clip."""

    def __init__(
        self,
        name: str,
        rng: np.random.Generator,
        *,
        variation: Variation = DEFAULT_VARIATION,
        description: str = "",
        sides: Sequence[float] | None = None,
    ):
        self.name = name
        self.rng = rng
        self.variation = variation
        self.description = description
        #: every side :meth:`sign` gave, in order (a held-out take replays its training take's)
        self.sides_drawn: list[float] = []
        self._replayed_sides = None if sides is None else [float(s) for s in sides]
        # drawn first, so a motion's own draws never shift the clip's tempo
        self.tempo = 1.0 + variation.tempo * float(rng.uniform(-1.0, 1.0))
        self._keys: dict[str, dict[float, tuple[float, str]]] = {}

    # --- seeded values -----------------------------------------------------
    def vary(self, value: float, spread: float) -> float:
        """``value`` moved by up to ``± spread`` (scaled by the variation's ``values``)."""
        return float(value) + float(spread) * self.variation.values * float(
            self.rng.uniform(-1.0, 1.0)
        )

    def factor(self, spread: float) -> float:
        """A multiplier ``1 ± spread`` (scaled by the variation's ``values``)."""
        return self.vary(1.0, spread)

    def sign(self) -> float:
        """+1 or -1 with equal odds (which side a motion favours this take).

        With ``sides`` given, the draw is still made (the take's other draws stay those of
        its seed) but the side returned is the next one of ``sides``: a new take of the
        same motion that points with the same hand and turns the same way.
        """
        drawn = 1.0 if self.rng.uniform() < 0.5 else -1.0
        if self._replayed_sides is not None:
            index = len(self.sides_drawn)
            if index >= len(self._replayed_sides):
                raise KeyframeError(
                    f"the motion asks for side {index + 1} but only "
                    f"{len(self._replayed_sides)} were given to replay",
                    clip=self.name,
                )
            drawn = self._replayed_sides[index]
        self.sides_drawn.append(drawn)
        return drawn

    # --- keys ----------------------------------------------------------------
    def key(
        self,
        control: str,
        frame: float,
        value: float,
        interpolation: Interpolation = "bezier",
    ) -> None:
        """One key. Keying the same value again at a frame only updates its interpolation."""
        frame, value = float(frame), float(value)
        if not np.isfinite(frame) or not np.isfinite(value):
            raise KeyframeError(
                f"key at frame {frame} has value {value}; frames and values must be finite",
                clip=self.name,
                control=control,
            )
        if interpolation not in INTERPOLATIONS:
            raise KeyframeError(
                f"interpolation {interpolation!r} is not one of {INTERPOLATIONS}",
                clip=self.name,
                control=control,
            )
        curve = self._keys.setdefault(control, {})
        previous = curve.get(frame)
        if previous is not None and abs(previous[0] - value) > 1e-9:
            raise KeyframeError(
                f"keyed twice at nominal frame {frame:g} with different values "
                f"({previous[0]:g} then {value:g})",
                clip=self.name,
                control=control,
            )
        curve[frame] = (value, interpolation)

    def pose(
        self, frame: float, values: Mapping[str, float], interpolation: Interpolation = "bezier"
    ) -> None:
        """Key several controls at one frame (a key pose)."""
        for control, value in values.items():
            self.key(control, frame, value, interpolation)

    def hold(self, control: str, start: float, end: float, value: float) -> None:
        """Keep ``control`` exactly at ``value`` from ``start`` to ``end`` (a plant, a hold).

        The first key is linear so the segment is flat; the last is Bézier so whatever
        follows eases out of the hold.
        """
        if not end > start:
            raise KeyframeError(
                f"a hold needs end > start, got {start:g}..{end:g}",
                clip=self.name,
                control=control,
            )
        self.key(control, start, value, "linear")
        self.key(control, end, value, "bezier")

    def value_at(self, control: str, frame: float) -> float | None:
        """The value keyed at a nominal frame, or None."""
        entry = self._keys.get(control, {}).get(float(frame))
        return None if entry is None else entry[0]

    @property
    def controls(self) -> list[str]:
        return list(self._keys)

    def nominal_curves(self) -> dict[str, FCurve]:
        """Each keyed control's curve at the nominal frames, before any timing variation.

        Draws nothing from the generator: reading a motion's design (to re-key it on
        another rig, say) leaves the clip's own timing draws untouched.
        """
        return {
            control: FCurve(
                [Key(frame, value, kind) for frame, (value, kind) in keys.items()], control=control
            )
            for control, keys in self._keys.items()
        }

    @property
    def nominal_frames(self) -> np.ndarray:
        """Every distinct nominal frame that carries a key, sorted."""
        frames = {f for curve in self._keys.values() for f in curve}
        return np.array(sorted(frames), dtype=np.float64)

    # --- the clip ----------------------------------------------------------------
    def time_warp(self) -> dict[float, int]:
        """Nominal key frame -> whole played frame: tempo and per-gap timing variation."""
        nominal = self.nominal_frames
        if nominal.size == 0:
            raise KeyframeError(
                "the clip has no keys; an empty clip animates nothing", clip=self.name
            )
        gaps = np.diff(nominal)
        stretch = self.tempo * (
            1.0 + self.variation.timing * self.rng.uniform(-1.0, 1.0, size=gaps.size)
        )
        played_gaps = np.maximum(1, np.rint(gaps * stretch)).astype(np.int64)
        start = int(np.rint(nominal[0] * self.tempo))
        played = start + np.concatenate([[0], np.cumsum(played_gaps)])
        return {float(f): int(p) for f, p in zip(nominal, played, strict=True)}

    def build(self) -> Clip:
        """The clip at 24 fps, keys moved to their played frames."""
        replayed = self._replayed_sides
        if replayed is not None and len(self.sides_drawn) != len(replayed):
            raise KeyframeError(
                f"{len(replayed)} sides were given to replay but the motion asked for "
                f"{len(self.sides_drawn)}",
                clip=self.name,
            )
        warp = self.time_warp()
        curves = {
            control: [
                Key(warp[frame], value, interpolation)
                for frame, (value, interpolation) in sorted(keys.items())
            ]
            for control, keys in self._keys.items()
        }
        return Clip(self.name, AUTHORED_FPS, curves, description=self.description)
