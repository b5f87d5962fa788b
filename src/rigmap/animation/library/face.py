"""The face's motion library: expressions and speech for training, extremes held out (§6.3).

Keys go on the face rig's 46 blendshape sliders (0..1, hard-clamped by the rig; the
Bézier curves never overshoot their keys, so keyed values inside the range stay
inside) and its jaw (``jaw.rx`` open, ``jaw.ry`` side, radians; ``jaw.tz`` forward,
cm). Expressions are blended from FACS-like presets with seeded intensity and
asymmetry; speech is a viseme track (mouth shapes every few frames, co-articulated by
the curves) with brow accents and blinks. Test clips push every group to the ends of
its range at once: a scream, a full sneer, a grimace, shouting.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources

import yaml

from rigmap.animation.library import Clips
from rigmap.animation.library.clip_builder import ClipBuilder

SIDED = (
    "brow_inner_up", "brow_outer_up", "brow_down", "brow_squeeze",
    "eye_blink", "eye_wide", "eye_squint",
    "cheek_raise", "cheek_puff", "cheek_suck",
    "nose_wrinkle", "nostril_flare",
    "mouth_smile", "mouth_frown", "mouth_stretch", "mouth_dimple", "mouth_press",
    "upper_lip_raise", "lower_lip_depress",
)  # fmt: skip
CENTER = (
    "mouth_pucker", "mouth_funnel", "mouth_roll_upper", "mouth_roll_lower",
    "mouth_shrug_upper", "mouth_shrug_lower", "mouth_close",
)  # fmt: skip
JAW = {"jaw_open": ("jaw.rx", 0.45), "jaw_side": ("jaw.ry", 0.15), "jaw_forward": ("jaw.tz", 0.6)}

# expression presets: slider -> weight (sided sliders apply to both sides); jaw in 0..1
EXPRESSIONS: dict[str, dict[str, float]] = {
    "neutral": {},
    "smile": {
        "mouth_smile": 0.8,
        "cheek_raise": 0.5,
        "eye_squint": 0.3,
        "mouth_dimple": 0.3,
        "jaw_open": 0.05,
    },
    "grin": {
        "mouth_smile": 1.0,
        "cheek_raise": 0.8,
        "eye_squint": 0.5,
        "upper_lip_raise": 0.4,
        "lower_lip_depress": 0.4,
        "mouth_stretch": 0.3,
        "jaw_open": 0.25,
    },
    "surprise": {
        "brow_inner_up": 0.8,
        "brow_outer_up": 0.9,
        "eye_wide": 0.8,
        "jaw_open": 0.45,
        "mouth_funnel": 0.3,
    },
    "anger": {
        "brow_down": 0.8,
        "brow_squeeze": 0.7,
        "eye_squint": 0.4,
        "nostril_flare": 0.5,
        "mouth_press": 0.6,
        "nose_wrinkle": 0.3,
        "jaw_forward": 0.3,
    },
    "sadness": {
        "brow_inner_up": 0.7,
        "brow_squeeze": 0.3,
        "mouth_frown": 0.7,
        "mouth_shrug_lower": 0.4,
        "eye_blink": 0.2,
    },
    "disgust": {
        "nose_wrinkle": 0.8,
        "upper_lip_raise": 0.7,
        "brow_down": 0.4,
        "eye_squint": 0.4,
        "mouth_frown": 0.3,
        "cheek_raise": 0.3,
    },
    "fear": {
        "brow_inner_up": 0.9,
        "brow_squeeze": 0.5,
        "eye_wide": 0.9,
        "mouth_stretch": 0.6,
        "jaw_open": 0.2,
        "lower_lip_depress": 0.3,
    },
    "contempt": {"mouth_dimple": 0.7, "mouth_smile": 0.2, "eye_squint": 0.2},
    "pout": {
        "mouth_pucker": 0.6,
        "mouth_shrug_lower": 0.6,
        "mouth_frown": 0.3,
        "brow_inner_up": 0.3,
    },
    "puff": {"cheek_puff": 0.9, "mouth_press": 0.5, "mouth_close": 0.4},
    "suck": {"cheek_suck": 0.8, "mouth_pucker": 0.5, "mouth_funnel": 0.3},
}
# visemes: mouth shapes of speech
VISEMES: dict[str, dict[str, float]] = {
    "rest": {"mouth_close": 0.1},
    "A": {"jaw_open": 0.55, "lower_lip_depress": 0.3, "upper_lip_raise": 0.1},
    "E": {"jaw_open": 0.28, "mouth_stretch": 0.5, "upper_lip_raise": 0.2},
    "I": {"jaw_open": 0.12, "mouth_stretch": 0.6, "mouth_smile": 0.2},
    "O": {"jaw_open": 0.45, "mouth_funnel": 0.6, "mouth_pucker": 0.3},
    "U": {"jaw_open": 0.15, "mouth_pucker": 0.8, "mouth_funnel": 0.4},
    "M": {"mouth_press": 0.6, "mouth_close": 0.6, "mouth_roll_upper": 0.2, "mouth_roll_lower": 0.2},
    "F": {"jaw_open": 0.08, "mouth_roll_lower": 0.6, "upper_lip_raise": 0.25},
    "L": {"jaw_open": 0.3, "mouth_stretch": 0.2, "mouth_shrug_upper": 0.2},
    "S": {"jaw_open": 0.05, "mouth_stretch": 0.4, "mouth_smile": 0.1, "mouth_close": 0.2},
}


@dataclass(frozen=True)
class Face:
    """Keys whole facial poses: every slider and the jaw, so a pose is a pose."""

    b: ClipBuilder

    def pose(
        self,
        frame: float,
        weights: dict[str, float],
        *,
        asymmetry: float = 0.0,
        shift: float = 0.0,
        jaw_side: float = 0.0,
    ) -> None:
        """Key every control: ``weights`` by slider (sided ones on both sides), 0 elsewhere.

        ``asymmetry`` > 0 favours the left side (< 0 the right), ``shift`` moves the
        mouth sideways (-1..1), ``jaw_side`` swings the jaw (-1..1 of its range).
        """
        b = self.b
        for name in SIDED:
            value = weights.get(name, 0.0)
            for side, sign in (("l", 1.0), ("r", -1.0)):
                b.key(f"{name}_{side}", frame, _unit(value * (1.0 + sign * asymmetry)))
        for name in CENTER:
            b.key(name, frame, _unit(weights.get(name, 0.0)))
        b.key("mouth_shift", frame, max(-1.0, min(1.0, shift)))
        for key, (control, full) in JAW.items():
            amount = jaw_side if key == "jaw_side" else weights.get(key, 0.0)
            low = -0.05 / 0.45 if key == "jaw_open" else (-1.0 if key == "jaw_side" else -0.4 / 0.6)
            b.key(control, frame, full * max(low, min(1.0, amount)))

    def blend(self, *parts: tuple[str | dict, float]) -> dict[str, float]:
        """A weighted mix of presets/visemes (names or dicts), clipped to [0, 1]."""
        mixed: dict[str, float] = {}
        for part, weight in parts:
            preset = part if isinstance(part, dict) else {**EXPRESSIONS, **VISEMES}[part]
            for name, value in preset.items():
                mixed[name] = mixed.get(name, 0.0) + weight * value
        return {name: _unit(value) for name, value in mixed.items()}

    def varied(self, weights: dict[str, float], spread: float = 0.12) -> dict[str, float]:
        return {name: _unit(self.b.vary(value, spread)) for name, value in weights.items()}


def _unit(value: float) -> float:
    return max(0.0, min(1.0, float(value)))


# this library's clip functions, in corpus order (see rigmap.animation.library.Clips)
clips = Clips()


#: the clips that are only beats, by name: ``face_beats.yaml`` beside this module
BEATS_FILE = "face_beats.yaml"


def _read_beats() -> dict[str, list[tuple]]:
    """Each beats-only clip's ``(frame, what, intensity, extras)`` rows from ``BEATS_FILE``."""
    text = resources.files("rigmap.animation.library").joinpath(BEATS_FILE).read_text("utf-8")
    beats = {}
    for clip, rows in (yaml.safe_load(text) or {}).items():
        if not all(isinstance(row, list) and len(row) == 4 for row in rows):
            raise ValueError(
                f"{BEATS_FILE}: clip {clip!r}: a beat is [frame, what, intensity, extras]"
            )
        beats[clip] = [tuple(row) for row in rows]
    return beats


BEATS = _read_beats()


def _beats_clip(name: str) -> Callable[[ClipBuilder], None]:
    """The keyframe function of a beats-only clip: its beats of ``BEATS_FILE``, keyed."""

    def keyframe(b: ClipBuilder) -> None:
        _expression_clip(b, BEATS[name])

    return keyframe


def _expression_clip(b: ClipBuilder, beats) -> None:
    """Key (frame, preset name / slider dict / list of (preset, weight), intensity, extras)
    beats; extras may fix the mouth ``shift`` and ``jaw_side``, else they wander a little."""
    face = Face(b)
    for frame, what, intensity, extra in beats:
        parts = [(what, intensity)] if isinstance(what, str | dict) else list(what)
        weights = face.varied(face.blend(*parts))
        face.pose(
            frame,
            weights,
            asymmetry=b.vary(0.0, 0.15),
            shift=(extra or {}).get("shift", b.vary(0.0, 0.08)),
            jaw_side=(extra or {}).get("jaw_side", b.vary(0.0, 0.15)),
        )


@clips.train("Smile & Laugh", "a smile grows into a laugh")
def smile_and_laugh(b: ClipBuilder) -> None:
    """A smile grows into a laugh (jaw bouncing), fades to a warm smile."""
    beats = [
        (0.0, "neutral", 0.0, None),
        (10.0, "smile", 0.6, None),
        (20.0, "smile", 1.0, None),
        (26.0, "grin", 0.9, None),
    ]
    for k in range(6):
        beats.append(
            (30.0 + 4.0 * k, [("grin", 1.0), ("A", 0.6 if k % 2 == 0 else 0.2)], 1.0, None)
        )
    beats += [(56.0, "grin", 0.7, None), (66.0, "smile", 0.6, None), (76.0, "smile", 0.4, None)]
    _expression_clip(b, beats)


clips.train("Surprise to Fear", "startle, gasp, worry")(_beats_clip("Surprise to Fear"))


@clips.train("Anger & Disgust", "anger builds, a sneer")
def anger_and_disgust(b: ClipBuilder) -> None:
    """Irritation builds to anger (jaw set forward), then a disgusted sneer."""
    side = b.sign()
    beats = [
        (0.0, "neutral", 0.0, None),
        (10.0, "anger", 0.4, None),
        (22.0, "anger", 0.9, None),
        (30.0, [("anger", 1.0), ("E", 0.3)], 1.0, None),
        (40.0, "anger", 0.7, None),
        (52.0, "disgust", 0.8, {"shift": 0.4 * side}),
        (62.0, "disgust", 1.0, {"shift": 0.5 * side, "jaw_side": 0.3 * side}),
        (74.0, "contempt", 0.8, {"shift": 0.3 * side}),
        (84.0, "neutral", 0.0, None),
    ]
    _expression_clip(b, beats)


clips.train("Sad Pout", "sadness, pout, puffed sigh, brave smile")(_beats_clip("Sad Pout"))


clips.train("Funny Faces", "cheeks sucked, lips rolled, jaw slid")(_beats_clip("Funny Faces"))


def _speech(
    b: ClipBuilder,
    text: str,
    *,
    energy: float,
    start: float = 0.0,
    rate: float = 3.0,
    mood: str | None = None,
    mood_amount: float = 0.0,
) -> float:
    """Key a viseme per letter group of ``text`` every ``rate`` frames from ``start``; returns
    the end frame.

    Letters map to visemes; a space is a short rest. Brows lift on stressed syllables
    and the eyes blink now and then, as people do while talking.
    """
    face = Face(b)
    letter = {
        "a": "A",
        "e": "E",
        "i": "I",
        "y": "I",
        "o": "O",
        "u": "U",
        "w": "U",
        "m": "M",
        "b": "M",
        "p": "M",
        "f": "F",
        "v": "F",
        "l": "L",
        "t": "L",
        "d": "L",
        "n": "L",
        "s": "S",
        "z": "S",
        "c": "S",
        "k": "E",
        "g": "E",
        "h": "A",
        "r": "O",
        "j": "I",
        "x": "S",
        "q": "U",
        " ": "rest",
    }
    frame = start
    previous = None
    for k, char in enumerate(text.lower()):
        viseme = letter.get(char, "rest")
        if viseme == previous and viseme != "rest":
            continue
        previous = viseme
        stress = 1.0 if k % 5 == 0 else 0.0
        parts = [(viseme, energy * b.factor(0.15))]
        if mood:
            parts.append((mood, mood_amount))
        weights = face.blend(*parts)
        weights["brow_inner_up"] = _unit(weights.get("brow_inner_up", 0.0) + 0.35 * stress)
        weights["brow_outer_up"] = _unit(weights.get("brow_outer_up", 0.0) + 0.25 * stress)
        if k % 17 == 11:
            weights["eye_blink"] = 1.0
        face.pose(
            frame,
            weights,
            asymmetry=b.vary(0.0, 0.1),
            shift=b.vary(0.0, 0.1),
            jaw_side=b.vary(0.0, 0.2),
        )
        frame += rate if viseme != "rest" else rate + 1.0
    face.pose(frame + 4.0, face.blend(("rest", 1.0), *([(mood, mood_amount)] if mood else [])))
    return frame + 4.0


@clips.train("Speech: Greeting", "'hello there, how are you today'")
def speech_greeting(b: ClipBuilder) -> None:
    _speech(b, "hello there how are you today", energy=0.9, mood="smile", mood_amount=0.4)


@clips.train("Speech: Counting", "counting to seven")
def speech_counting(b: ClipBuilder) -> None:
    _speech(b, "one two three four five six seven", energy=0.8)


@clips.train("Speech: Complaint", "an annoyed sentence")
def speech_complaint(b: ClipBuilder) -> None:
    _speech(b, "i told you not to move my things", energy=1.0, mood="anger", mood_amount=0.5)


@clips.train("Blinks & Glances", "listening: blinks, a squint, a smile")
def blinks_and_glances(b: ClipBuilder) -> None:
    """Listening: slow blinks, a squint of thought, a half smile."""
    face = Face(b)
    for frame, weights in (
        (0.0, {}),
        (6.0, {"eye_blink": 1.0}),
        (9.0, {}),
        (20.0, {"eye_squint": 0.5, "brow_down": 0.3, "mouth_press": 0.3}),
        (30.0, {"eye_squint": 0.6, "brow_down": 0.4, "mouth_press": 0.4, "mouth_dimple": 0.3}),
        (34.0, {"eye_blink": 1.0, "brow_down": 0.3}),
        (37.0, {"brow_outer_up": 0.3}),
        (48.0, {"mouth_smile": 0.4, "cheek_raise": 0.2, "brow_outer_up": 0.3}),
        (58.0, {"eye_blink": 0.9, "mouth_smile": 0.35}),
        (61.0, {"mouth_smile": 0.3}),
        (72.0, {"nostril_flare": 0.4, "eye_wide": 0.3}),
        (80.0, {}),
    ):
        face.pose(frame, face.varied(weights, 0.08), asymmetry=b.vary(0.0, 0.2))


# --- test: extremes --------------------------------------------------------------------------
@clips.test("Extreme Expressions", "every slider group at its end")
def extreme_expressions(b: ClipBuilder) -> None:
    """Every group at the end of its range: a scream, a full sneer, a grimace, a huge pout."""
    face = Face(b)
    scream = {
        "jaw_open": 1.0,
        "mouth_stretch": 1.0,
        "brow_inner_up": 1.0,
        "brow_outer_up": 1.0,
        "eye_wide": 1.0,
        "lower_lip_depress": 1.0,
        "upper_lip_raise": 0.8,
        "nostril_flare": 1.0,
        "jaw_forward": 0.6,
    }
    sneer = {
        "nose_wrinkle": 1.0,
        "upper_lip_raise": 1.0,
        "brow_down": 1.0,
        "brow_squeeze": 1.0,
        "eye_squint": 1.0,
        "cheek_raise": 1.0,
        "mouth_frown": 0.6,
    }
    grimace = {
        "mouth_stretch": 1.0,
        "mouth_press": 1.0,
        "mouth_frown": 1.0,
        "eye_blink": 1.0,
        "brow_squeeze": 1.0,
        "brow_down": 0.8,
        "cheek_suck": 0.6,
        "mouth_close": 1.0,
    }
    pout = {
        "mouth_pucker": 1.0,
        "mouth_funnel": 1.0,
        "cheek_puff": 1.0,
        "mouth_shrug_upper": 1.0,
        "mouth_shrug_lower": 1.0,
        "brow_inner_up": 1.0,
    }
    for frame, weights, asym, shift, jaw_side in (
        (0.0, {}, 0.0, 0.0, 0.0),
        (5.0, scream, 0.0, 0.0, 0.0),
        (14.0, scream, 0.2, 0.0, 1.0),
        (19.0, sneer, 0.6, 1.0, 0.5),
        (28.0, sneer, -0.6, -1.0, -1.0),
        (33.0, grimace, 0.0, 0.0, 0.0),
        (41.0, {**grimace, "jaw_open": 0.9}, 0.3, 0.5, 1.0),
        (46.0, pout, 0.0, -1.0, 0.0),
        (54.0, {**pout, "jaw_forward": 1.0}, 0.0, 1.0, -0.6),
        (59.0, {**scream, **sneer}, 0.0, 0.0, 0.0),
        (66.0, {}, 0.0, 0.0, 0.0),
    ):
        face.pose(frame, weights, asymmetry=asym, shift=shift, jaw_side=jaw_side)


@clips.test("Shouting", "yelling with fast, wide mouth shapes")
def shouting(b: ClipBuilder) -> None:
    """Yelling across a field: wide jaw, stretched lips, brows slammed up, fast visemes."""
    _speech(
        b,
        "hey get away from there now",
        start=0.0,
        rate=2.0,
        energy=1.6,
        mood="surprise",
        mood_amount=0.6,
    )


LIBRARY = clips.library("face")
