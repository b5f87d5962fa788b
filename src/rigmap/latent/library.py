"""Labelled training sets and one latent model per label (Bailey et al. 2016, §5, §6).

A :class:`Take` is one clip's used-control values with its label; :func:`labelled_sets`
groups takes by label and checks them (every take labelled, every label with enough
frames); :func:`fit_models` fits a :class:`~rigmap.latent.LatentModel` per label, each
take one segment of its dynamics prior. :func:`face_expression_sets` builds the face's
labelled expression library (:mod:`rigmap.animation.library.face_expressions`).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rigmap.latent.errors import LatentInputError
from rigmap.latent.gplvm import GPLVMSettings
from rigmap.latent.model import LatentModel

MIN_LABEL_FRAMES = 24  # ours: one second at 24 fps; fewer cannot show an expression's range


@dataclass(frozen=True)
class Take:
    label: str | None
    name: str
    values: np.ndarray  # (F, C_used)


@dataclass
class LabelledSet:
    """One label's takes, in order; rows of ``values`` are the takes one after another."""

    label: str
    names: list[str]
    takes: list[np.ndarray]

    @property
    def values(self) -> np.ndarray:
        return np.vstack(self.takes)

    @property
    def segments(self) -> np.ndarray:
        return np.concatenate(
            [
                np.full(len(v), name, dtype=object)
                for name, v in zip(self.names, self.takes, strict=True)
            ]
        )

    @property
    def n_frames(self) -> int:
        return sum(len(v) for v in self.takes)

    def take(self, name: str) -> np.ndarray:
        if name not in self.names:
            raise LatentInputError(
                f"set {self.label!r} has no take named {name!r}; takes: {self.names}"
            )
        return self.takes[self.names.index(name)]

    def rows(self, name: str) -> np.ndarray:
        """Row indices of one take in ``values``."""
        starts = np.cumsum([0] + [len(v) for v in self.takes])
        k = self.names.index(name)
        return np.arange(starts[k], starts[k + 1])


def labelled_sets(
    takes: Sequence[Take], *, n_controls: int, min_frames: int = MIN_LABEL_FRAMES
) -> dict[str, LabelledSet]:
    """Group takes by label (in order of first appearance), checking every take.

    Errors name the take: an unlabelled take, a take of the wrong width or with
    non-finite values, a repeated take name, and a label whose takes hold fewer than
    ``min_frames`` frames together."""
    sets: dict[str, LabelledSet] = {}
    seen: set[str] = set()
    for take in takes:
        if take.label is None or not str(take.label).strip():
            raise LatentInputError(
                f"clip {take.name!r} has no label; every training clip needs one "
                f"(e.g. happy, grumpy, neutral)"
            )
        if take.name in seen:
            raise LatentInputError(f"two takes are named {take.name!r}; take names must be unique")
        seen.add(take.name)
        values = np.asarray(take.values, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != n_controls:
            raise LatentInputError(
                f"clip {take.name!r} (label {take.label!r}): expected (frames, {n_controls}) "
                f"control values, got shape {values.shape}"
            )
        if not np.isfinite(values).all():
            row = int(np.argwhere(~np.isfinite(values))[0, 0])
            raise LatentInputError(
                f"clip {take.name!r} (label {take.label!r}) has non-finite values at frame {row}"
            )
        entry = sets.setdefault(take.label, LabelledSet(take.label, [], []))
        entry.names.append(take.name)
        entry.takes.append(values)
    if not sets:
        raise LatentInputError("no labelled takes were given")
    short = {label: s.n_frames for label, s in sets.items() if s.n_frames < min_frames}
    if short:
        raise LatentInputError(
            f"labels with fewer than {min_frames} frames: "
            + ", ".join(f"{label!r} has {n}" for label, n in short.items())
        )
    return sets


def labels_of_clips(clip_names: Sequence[str], labels: Mapping[str, str]) -> list[str]:
    """The label of every clip by name; an unlabelled clip is an error naming it."""
    missing = [name for name in clip_names if not labels.get(name)]
    if missing:
        raise LatentInputError(f"clips without a label: {missing}; label every training clip")
    return [labels[name] for name in clip_names]


@dataclass
class FittedModels:
    """A latent model per label, their sets and fit seconds."""

    models: dict[str, LatentModel]
    sets: dict[str, LabelledSet]
    fit_seconds: dict[str, float] = field(default_factory=dict)

    def model(self, label: str) -> LatentModel:
        if label not in self.models:
            raise LatentInputError(f"no model named {label!r}; models: {sorted(self.models)}")
        return self.models[label]


def fit_models(
    rig,
    sets: Mapping[str, LabelledSet],
    *,
    fps: float = 24.0,
    settings: GPLVMSettings | None = None,
    variance: float = 0.85,
    n_pca: int | None = None,
) -> FittedModels:
    """One latent model per labelled set (§5: a GPLVM per expression)."""
    models, seconds = {}, {}
    for label, entry in sets.items():
        start = time.perf_counter()
        models[label] = fit_set(
            rig, entry, fps=fps, settings=settings, variance=variance, n_pca=n_pca
        )
        seconds[label] = time.perf_counter() - start
    return FittedModels(models, dict(sets), seconds)


def fit_set(
    rig,
    entry: LabelledSet,
    *,
    fps: float,
    settings: GPLVMSettings | None = None,
    variance: float = 0.85,
    n_pca: int | None = None,
) -> LatentModel:
    """One labelled set's latent model: the stage's fits, the measures' refits and the
    figure's refit without the prior all go through here."""
    return LatentModel.fit(
        rig,
        entry.values,
        entry.segments,
        fps=fps,
        variance=variance,
        n_pca=n_pca,
        settings=settings,
    )


def face_expression_sets(rig, *, labels=None, **take) -> dict[str, LabelledSet]:
    """The face's expression library as labelled sets (training, or held out).

    ``labels``: which expressions (all when None); ``take`` is the keywords of
    :func:`rigmap.animation.library.face_expressions.build_takes` (``seed``, ``size``,
    ``takes``, ``heldout``, ``coordinated``: how takes vary), passed on as they are.
    """
    from rigmap.animation.library import face_expressions as fx

    chosen = fx.LABELS if labels is None else tuple(labels)
    built = fx.build_takes(labels=chosen, **take)
    return labelled_sets(
        [Take(t.label, t.name, fx.take_values(t, rig)) for t in built],
        n_controls=len(rig.controls.used_indices),
    )


#: the squirrel's labelled sets (ours): motions of its keyframed library, each played as
#: seeded takes; "groom" ends in the head shake the paper plays as a segment (§5.3)
SQUIRREL_LABELS: dict[str, str] = {
    "look": "Look Around",
    "nibble": "Nibble",
    "groom": "Groom",
    "stretch": "Stretch Up",
    "tail": "Tail Flick",
}
LIBRARY_TAKES: dict[str, tuple[int, int]] = {"quick": (2, 1), "paper": (6, 2)}  # ours


def library_sets(
    rig,
    motions: Mapping[str, str],
    *,
    seed: int = 0,
    size: str = "quick",
    labels=None,
    heldout: bool = False,
) -> dict[str, LabelledSet]:
    """Labelled sets from a rig's motion library: label → motion name, each played as
    seeded takes ``"<label> <k>"`` (held out: seeds moved by the library's offset)."""
    from rigmap.animation.library import HELDOUT_SEED_OFFSET, build_clip, motion_library

    if size not in LIBRARY_TAKES:
        raise LatentInputError(f"library size must be one of {list(LIBRARY_TAKES)}, got {size!r}")
    chosen = list(motions) if labels is None else list(labels)
    unknown = [label for label in chosen if label not in motions]
    if unknown:
        raise LatentInputError(f"{rig.name} has no labelled set {unknown}; labels: {list(motions)}")
    library = motion_library(rig.name)
    count = LIBRARY_TAKES[size][1 if heldout else 0]
    used = rig.controls.used_indices
    defaults = rig.controls.defaults[used]
    takes = []
    for label in chosen:
        _, motion = library.find(motions[label])
        for k in range(count):
            take_seed = seed + k + (HELDOUT_SEED_OFFSET if heldout else 0)
            clip = build_clip(rig.name, motion, seed=take_seed)
            name = f"{label} {'heldout ' if heldout else ''}{k}"
            takes.append(Take(label, name, clip.evaluate(rig.used_controls, defaults)))
    return labelled_sets(takes, n_controls=len(used))


def rig_sets(rig, *, seed: int = 0, size: str = "quick", labels=None, heldout: bool = False):
    """The labelled sets of a built-in rig: the face's expressions or the squirrel's motions."""
    if rig.name == "face":
        return face_expression_sets(rig, seed=seed, size=size, labels=labels, heldout=heldout)
    if rig.name == "squirrel":
        return library_sets(
            rig, SQUIRREL_LABELS, seed=seed, size=size, labels=labels, heldout=heldout
        )
    raise LatentInputError(
        f"rig {rig.name!r} has no labelled sets for latent synthesis; rigs: face, squirrel"
    )
