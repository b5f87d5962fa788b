"""The face's labelled expression library for latent synthesis (Bailey et al. 2016, §6).

Eight labels, as the paper's Toothless sets (its "head shake" has no counterpart on a
face without a neck; "talk" takes its place): happy, grumpy, bored, curious, neutral,
roar, surprise, talk. Each label is one keyframed motion (key poses on the face's 46
sliders and its jaw, built from :mod:`rigmap.animation.library.face`'s presets) played
as several *takes*: each take draws its own timing (tempo and per-gap spacing) and
values (intensities, asymmetry, mouth shift) from a generator seeded by
``(seed, "face", take name)``, so takes of a label differ the way two animators' takes
of one brief would. All takes are at 24 fps and start and end near rest, as shots of
a film do.

Sizes (ours): ``quick`` is 3 training takes per label (about 150 frames per label) and
1 held-out take; ``paper`` is 8 training takes (about 400 frames, inside the paper's
100–800) and 2 held-out takes. Held-out takes are new draws (the seed moved by
:data:`HELDOUT_SEED_OFFSET`), never a training take.

How values vary between takes (ours), ``coordinated``:

- ``None`` (the library's takes, every stage's): each key pose draws its own intensity
  slider by slider (± 0.12), its own asymmetry, mouth shift and jaw swing — a label's
  takes then differ in dozens of independent ways, and a label's frames span many
  dimensions (measured by ``benchmarks/latent_knee.py``);
- ``k`` in 0–3: each take draws ``k`` numbers once, in this order — an intensity
  (``1 ± 0.25`` on every weight), an asymmetry (± 0.3) and a mouth shift (± 0.15) — and
  every key pose of the take uses them, with no per-slider jitter (the jaw's side swing
  stays 0): one expression played with a few coordinated controls. Timing varies as in
  every take, and grumpy and curious draw the side they favour per take either way.
  Only the keyed expressions use it; ``talk`` (speech) keeps its own draws.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rigmap.animation.clip import Clip
from rigmap.animation.library import clip_rng
from rigmap.animation.library.clip_builder import AUTHORED_FPS, ClipBuilder
from rigmap.animation.library.face import Face, _speech

LABELS: tuple[str, ...] = (
    "happy",
    "grumpy",
    "bored",
    "curious",
    "neutral",
    "roar",
    "surprise",
    "talk",
)
SIZES: dict[str, tuple[int, int]] = {"quick": (3, 1), "paper": (8, 2)}  # (train, held out)
HELDOUT_SEED_OFFSET = 1_000_000  # ours, as the corpus library's
RIG = "face"


#: ours: a coordinated take's spreads, in the order its factors are drawn (module docstring)
COORDINATED_SPREADS: tuple[tuple[str, float], ...] = (
    ("intensity", 0.25),
    ("asymmetry", 0.3),
    ("shift", 0.15),
)


class ExpressionBuilder(ClipBuilder):
    """A :class:`ClipBuilder` whose take may be *coordinated*: ``factors`` holds the take's
    intensity, asymmetry and mouth shift, used by every key pose (None: every key pose
    draws its own values, the library's takes)."""

    def __init__(self, name: str, rng: np.random.Generator, *, coordinated: int | None, **kw):
        super().__init__(name, rng, **kw)  # draws the tempo first, as every take does
        self.factors: dict[str, float] | None = None
        if coordinated is not None:
            if not 0 <= coordinated <= len(COORDINATED_SPREADS):
                raise ValueError(
                    f"coordinated takes draw 0-{len(COORDINATED_SPREADS)} factors, "
                    f"got {coordinated!r}"
                )
            self.factors = {"intensity": 1.0, "asymmetry": 0.0, "shift": 0.0}
            for key, spread in COORDINATED_SPREADS[:coordinated]:
                self.factors[key] = self.vary(self.factors[key], spread)


def _beats(b: ClipBuilder, beats) -> None:
    """Key ``(frame, parts, extras)`` beats; ``parts`` a preset name, a slider dict or a
    list of ``(preset, weight)``; extras fix ``shift``/``jaw_side``/``asymmetry``."""
    factors = getattr(b, "factors", None)
    if factors is not None:
        _coordinated_beats(b, beats, factors)
        return
    face = Face(b)
    for frame, what, extra in beats:
        extra = extra or {}
        parts = [(what, 1.0)] if isinstance(what, str | dict) else list(what)
        weights = face.varied(face.blend(*parts), extra.get("spread", 0.12))
        face.pose(
            frame,
            weights,
            asymmetry=extra.get("asymmetry", b.vary(0.0, 0.15)),
            shift=extra.get("shift", b.vary(0.0, 0.08)),
            jaw_side=extra.get("jaw_side", b.vary(0.0, 0.12)),
        )


def _coordinated_beats(b: ClipBuilder, beats, factors: dict[str, float]) -> None:
    """The beats of one coordinated take: every pose at the take's intensity, asymmetry and
    mouth shift (a beat's extras still fix its own), no per-slider or per-pose draws."""
    face = Face(b)
    for frame, what, extra in beats:
        extra = extra or {}
        parts = [(what, 1.0)] if isinstance(what, str | dict) else list(what)
        weights = {n: v * factors["intensity"] for n, v in face.blend(*parts).items()}
        face.pose(
            frame,
            {n: min(1.0, v) for n, v in weights.items()},
            asymmetry=extra.get("asymmetry", factors["asymmetry"]),
            shift=extra.get("shift", factors["shift"]),
            jaw_side=extra.get("jaw_side", 0.0),
        )


def happy(b: ClipBuilder) -> None:
    """A smile that grows into a short laugh and settles warm."""
    laugh = [
        (4.0 * k + 18.0, [("grin", 0.9), ("A", 0.5 if k % 2 == 0 else 0.15)]) for k in range(4)
    ]
    _beats(
        b,
        [(0.0, "neutral", {"spread": 0.0}), (6.0, [("smile", 0.6)], None), (12.0, "smile", None)]
        + [(f, w, None) for f, w in laugh]
        + [(38.0, [("grin", 0.6)], None), (46.0, [("smile", 0.7)], None)],
    )


def grumpy(b: ClipBuilder) -> None:
    """A scowl: brows down, lips pressed, a sour sideways twist."""
    side = b.sign()
    _beats(
        b,
        [
            (0.0, "neutral", {"spread": 0.0}),
            (8.0, [("anger", 0.5), ("sadness", 0.2)], None),
            (16.0, [("anger", 0.8), ("contempt", 0.3)], {"shift": 0.3 * side}),
            (26.0, [("anger", 0.6), ("disgust", 0.3)], {"shift": 0.4 * side}),
            (36.0, [("anger", 0.7), ("pout", 0.3)], None),
            (46.0, [("anger", 0.3), ("sadness", 0.2)], None),
        ],
    )


def bored(b: ClipBuilder) -> None:
    """Heavy lids, a slow sigh through puffed cheeks, a long blink."""
    lids = {"eye_blink": 0.45, "brow_inner_up": 0.15, "mouth_frown": 0.2}
    _beats(
        b,
        [
            (0.0, "neutral", {"spread": 0.0}),
            (10.0, lids, None),
            (20.0, [(lids, 1.0), ("puff", 0.5)], None),
            (28.0, [(lids, 1.0), ("O", 0.3)], None),
            (36.0, {**lids, "eye_blink": 0.95}, None),
            (42.0, lids, None),
            (52.0, {**lids, "eye_blink": 0.35}, None),
        ],
    )


def curious(b: ClipBuilder) -> None:
    """One brow up, a squint, lips pursed to one side, then interest."""
    side = b.sign()
    _beats(
        b,
        [
            (0.0, "neutral", {"spread": 0.0}),
            (8.0, {"brow_outer_up": 0.7, "eye_squint": 0.3}, {"asymmetry": 0.8 * side}),
            (
                18.0,
                {
                    "brow_outer_up": 0.8,
                    "brow_inner_up": 0.3,
                    "eye_squint": 0.5,
                    "mouth_pucker": 0.4,
                },
                {"asymmetry": 0.7 * side, "shift": 0.5 * side},
            ),
            (30.0, {"brow_inner_up": 0.5, "eye_wide": 0.4, "mouth_pucker": 0.2}, None),
            (40.0, [("smile", 0.3), ({"brow_outer_up": 0.4}, 1.0)], {"asymmetry": 0.4 * side}),
        ],
    )


def neutral(b: ClipBuilder) -> None:
    """At rest: breathing-small changes, two blinks, a glance of the mouth."""
    _beats(
        b,
        [
            (0.0, "neutral", {"spread": 0.0}),
            (10.0, {"mouth_close": 0.1, "brow_inner_up": 0.05}, None),
            (14.0, {"eye_blink": 1.0}, None),
            (17.0, {"mouth_close": 0.1}, None),
            (30.0, {"mouth_press": 0.15, "brow_down": 0.05}, None),
            (38.0, {"eye_blink": 0.9}, None),
            (41.0, {}, None),
            (50.0, {"mouth_close": 0.05}, None),
        ],
    )


def roar(b: ClipBuilder) -> None:
    """Wind-up, a wide roar with the lip curled and the nose wrinkled, then release."""
    full = {
        "jaw_open": 1.0,
        "upper_lip_raise": 0.9,
        "lower_lip_depress": 0.8,
        "mouth_stretch": 0.7,
        "nose_wrinkle": 0.8,
        "brow_down": 0.8,
        "brow_squeeze": 0.6,
        "eye_squint": 0.6,
        "nostril_flare": 0.9,
    }
    _beats(
        b,
        [
            (0.0, "neutral", {"spread": 0.0}),
            (6.0, [("anger", 0.6)], None),
            (10.0, {"mouth_close": 0.6, "brow_down": 0.6, "nostril_flare": 0.6}, None),
            (16.0, full, None),
            (24.0, {**full, "jaw_open": 0.9}, None),
            (32.0, {**full, "jaw_open": 0.75}, None),
            (40.0, [("anger", 0.5), ("A", 0.2)], None),
            (50.0, [("anger", 0.2)], None),
        ],
    )


def surprise(b: ClipBuilder) -> None:
    """A startle: brows shoot up, eyes wide, jaw drops, then a relieved half smile."""
    _beats(
        b,
        [
            (0.0, "neutral", {"spread": 0.0}),
            (4.0, [("surprise", 0.3)], None),
            (8.0, "surprise", None),
            (16.0, [("surprise", 0.9), ("O", 0.4)], None),
            (28.0, [("surprise", 0.6)], None),
            (40.0, [("surprise", 0.25), ("smile", 0.3)], None),
        ],
    )


TEXTS = (
    "hello there how are you",
    "we should go now",
    "look at that one",
    "i think so too",
    "not today thank you",
    "where did it go",
    "that was fun",
    "come over here",
)


def talk(b: ClipBuilder) -> None:
    """A short sentence (chosen by the take's generator): visemes, brow accents, blinks."""
    text = TEXTS[int(b.rng.integers(len(TEXTS)))]
    _speech(b, text, energy=0.85, rate=3.0)


MOTIONS: dict[str, Callable[[ClipBuilder], None]] = {
    "happy": happy,
    "grumpy": grumpy,
    "bored": bored,
    "curious": curious,
    "neutral": neutral,
    "roar": roar,
    "surprise": surprise,
    "talk": talk,
}


@dataclass(frozen=True)
class ExpressionTake:
    """One take: its label, its name (``"<label> <k>"``), and its clip at 24 fps."""

    label: str
    name: str
    clip: Clip


def take_name(label: str, index: int, heldout: bool = False) -> str:
    return f"{label} {'heldout ' if heldout else ''}{index}"


def build_take(
    label: str, index: int, *, seed: int, heldout: bool = False, coordinated: int | None = None
) -> ExpressionTake:
    """One seeded take of one label (``coordinated``: the module docstring)."""
    if label not in MOTIONS:
        raise KeyError(f"the face has no expression {label!r}; labels: {list(LABELS)}")
    name = take_name(label, index, heldout)
    rng = clip_rng(seed + (HELDOUT_SEED_OFFSET if heldout else 0), RIG, name)
    builder = ExpressionBuilder(
        name, rng, coordinated=coordinated, description=f"{label} expression, take {index}"
    )
    MOTIONS[label](builder)
    clip = builder.build()
    assert clip.fps == AUTHORED_FPS
    return ExpressionTake(label, name, clip)


def build_takes(
    *,
    seed: int = 0,
    size: str = "quick",
    labels=LABELS,
    takes: int | None = None,
    heldout: bool = False,
    coordinated: int | None = None,
) -> list[ExpressionTake]:
    """Every take of ``labels`` (training, or held out with ``heldout=True``).

    ``takes`` overrides the size's count per label; ``coordinated``: the module docstring."""
    if size not in SIZES:
        raise KeyError(f"expression library size must be one of {list(SIZES)}, got {size!r}")
    count = takes if takes is not None else SIZES[size][1 if heldout else 0]
    return [
        build_take(label, k, seed=seed, heldout=heldout, coordinated=coordinated)
        for label in labels
        for k in range(count)
    ]


def take_values(take: ExpressionTake, rig) -> np.ndarray:
    """``(F, C_used)`` used-control values of a take on ``rig`` (unkeyed ones at default)."""
    used = rig.controls.used_indices
    return take.clip.evaluate(rig.used_controls, rig.controls.defaults[used])
