"""The animator's motion library: per-rig keyframed clips, split into train and test (§6.1).

Each built-in rig has a module here (named by its manifest,
:mod:`rigmap.rigs.manifest`) that keys its *used* controls the way an animator
would (key poses, plants, overlap), with seeded variation of timing and values;
Rigify's wolf (a Blender rig) gets the dog's motions re-keyed onto its own
controls (:mod:`.wolf`). Training clips are everyday motions; test clips are held out
and chosen to be large, fast or extreme, as in the paper's Table 1.

``build_clips(rig, split, seed=...)`` gives the clips; ``build_corpus`` plays them on
the rig's used controls into a :class:`~rigmap.animation.corpus.Corpus`. The same
seed always gives the same clips; each clip draws from its own generator, seeded by
``(seed, rig, clip name)``, so adding a clip never changes the others.
"""

from __future__ import annotations

import importlib
import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rigmap.animation.clip import CLIP_FPS, Clip
from rigmap.animation.corpus import Corpus
from rigmap.animation.library.clip_builder import (
    AUTHORED_FPS,
    DEFAULT_VARIATION,
    ClipBuilder,
    Variation,
)
from rigmap.rigs.manifest import all_manifests
from rigmap.store.layout import HELDOUT

SPLITS: tuple[str, str] = ("train", "test")


@dataclass(frozen=True)
class Motion:
    """One clip recipe: a name, a description, and the function that keys it."""

    name: str
    keyframe: Callable[[ClipBuilder], None]
    description: str


@dataclass(frozen=True)
class MotionLibrary:
    """A rig's training motions and its held-out test motions."""

    rig: str
    train: tuple[Motion, ...]
    test: tuple[Motion, ...]

    def motions(self, split: str) -> tuple[Motion, ...]:
        _check_split(split)
        return self.train if split == "train" else self.test

    def find(self, clip_name: str) -> tuple[str, Motion]:
        """``(split, motion)`` for a clip name."""
        for split in SPLITS:
            for motion in self.motions(split):
                if motion.name == clip_name:
                    return split, motion
        names = [m.name for split in SPLITS for m in self.motions(split)]
        raise KeyError(f"rig {self.rig!r} has no clip named {clip_name!r}; clips: {names}")


class Clips:
    """A library's clip functions, declared where they are defined, in that order.

    ``@clips.train("Walk", "two strides …")`` above a clip function adds it to the
    training motions (``@clips.test`` to the held-out ones); ``clips.library(rig)``
    is the rig's :class:`MotionLibrary`. The order of definition is the corpus order.
    """

    def __init__(self) -> None:
        self._motions: dict[str, list[Motion]] = {split: [] for split in SPLITS}

    def train(self, name: str, description: str) -> Callable:
        return self._declare("train", name, description)

    def test(self, name: str, description: str) -> Callable:
        return self._declare("test", name, description)

    def _declare(self, split: str, name: str, description: str) -> Callable:
        def declare(keyframe: Callable[[ClipBuilder], None]) -> Callable[[ClipBuilder], None]:
            self._motions[split].append(Motion(name, keyframe, description))
            return keyframe

        return declare

    def library(self, rig: str) -> MotionLibrary:
        return MotionLibrary(rig, *(tuple(self._motions[split]) for split in SPLITS))


def libraries() -> list[str]:
    """Rig names whose manifest names a motion library."""
    return sorted(name for name, m in all_manifests().items() if m.library is not None)


def motion_library(rig_name: str) -> MotionLibrary:
    """The motion library a rig's manifest names (the ``LIBRARY`` of that module)."""
    known = all_manifests().get(rig_name)
    if known is None or known.library is None:
        raise KeyError(f"no motion library for rig {rig_name!r}; libraries exist for {libraries()}")
    return importlib.import_module(known.library).LIBRARY


def clip_rng(seed: int, rig_name: str, clip_name: str) -> np.random.Generator:
    """The generator one clip draws from: depends on the seed, the rig and the clip only."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return np.random.default_rng(
        [int(seed), zlib.crc32(rig_name.encode()), zlib.crc32(clip_name.encode())]
    )


def build_clip(
    rig_name: str,
    motion: Motion,
    *,
    seed: int,
    fps: int = AUTHORED_FPS,
    variation: Variation = DEFAULT_VARIATION,
    sides_of_seed: int | None = None,
) -> Clip:
    """Key one motion with its seeded variation; retimed if ``fps`` is not 24.

    With ``sides_of_seed``, the take keeps the sides and directions of that seed's take
    (which hand points, which way it turns) and draws everything else from ``seed``.
    """
    if fps not in CLIP_FPS:
        raise ValueError(f"fps must be one of {CLIP_FPS}, got {fps!r}")
    sides = None
    if sides_of_seed is not None:
        source = _builder(rig_name, motion, sides_of_seed, variation)
        motion.keyframe(source)
        sides = source.sides_drawn
    builder = _builder(rig_name, motion, seed, variation, sides=sides)
    motion.keyframe(builder)
    clip = builder.build()
    return clip if fps == AUTHORED_FPS else clip.retimed(fps)


def _builder(rig_name, motion, seed, variation, sides=None) -> ClipBuilder:
    return ClipBuilder(
        motion.name,
        clip_rng(seed, rig_name, motion.name),
        variation=variation,
        description=motion.description,
        sides=sides,
    )


def build_clips(rig_name: str, split: str, **take) -> list[Clip]:
    """Every clip of one split of a rig's library, each keyed by :func:`build_clip`.

    ``take`` is :func:`build_clip`'s keywords (``seed``, ``fps``, ``variation``,
    ``sides_of_seed``), passed on as they are so that their defaults live in one place.
    """
    return [
        build_clip(rig_name, motion, **take) for motion in motion_library(rig_name).motions(split)
    ]


#: added to the seed for the held-out takes, so they are new draws of the training
#: motions' seeded variation, never a training take (ours)
HELDOUT_SEED_OFFSET = 1_000_000

#: how a held-out take picks its sides: ``training`` keeps its training take's (a new
#: take of the same motion), ``drawn`` draws them anew (a mirrored motion may come out)
HELDOUT_SIDES = ("training", "drawn")


def build_corpus(
    rig,
    split: str,
    *,
    seed: int,
    fps: int = AUTHORED_FPS,
    variation: Variation = DEFAULT_VARIATION,
    heldout_sides: str = "training",
) -> Corpus:
    """Play a split of the rig's library on its used controls (unkeyed ones at default).

    Split ``heldout`` is the training motions played again with the seed moved by
    ``HELDOUT_SEED_OFFSET``: other takes of what the mapping learned from, the
    in-distribution test set beside the library's extreme test clips (issue #15). With
    ``heldout_sides="training"`` each keeps its training take's sides (``HELDOUT_SIDES``):
    a take that turns the other way is a mirrored motion the corpus never had.
    """
    if heldout_sides not in HELDOUT_SIDES:
        raise ValueError(f"heldout_sides must be one of {HELDOUT_SIDES}, got {heldout_sides!r}")
    if split == HELDOUT:
        clips = build_clips(
            rig.name,
            "train",
            seed=seed + HELDOUT_SEED_OFFSET,
            fps=fps,
            variation=variation,
            sides_of_seed=seed if heldout_sides == "training" else None,
        )
    else:
        clips = build_clips(rig.name, split, seed=seed, fps=fps, variation=variation)
    used = rig.controls.used_indices
    return Corpus.from_clips(
        clips,
        rig.used_controls,
        rig.controls.defaults[used],
        rig=rig.name,
        split=split,
        seed=seed,
        lower=rig.controls.lower[used],
        upper=rig.controls.upper[used],
        extra={
            "variation": {
                "tempo": variation.tempo,
                "timing": variation.timing,
                "values": variation.values,
            },
            "authored_fps": AUTHORED_FPS,
            **({"heldout_sides": heldout_sides} if split == HELDOUT else {}),
        },
    )


def _check_split(split: str) -> None:
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")


__all__ = [
    "HELDOUT_SEED_OFFSET",
    "HELDOUT_SIDES",
    "SPLITS",
    "ClipBuilder",
    "Clips",
    "Motion",
    "MotionLibrary",
    "Variation",
    "build_clip",
    "build_clips",
    "build_corpus",
    "clip_rng",
    "libraries",
    "motion_library",
]
