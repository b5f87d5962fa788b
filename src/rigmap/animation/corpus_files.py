"""A rig's corpora and their poses at the :class:`~rigmap.store.Layout`'s paths.

The ``animate`` stage plays the rig's motion library into ``data/<rig>/corpus/<split>.parquet``
(:func:`write_corpora`), the ``pose`` stage evaluates the rig on every frame into
``data/<rig>/poses/<split>.parquet`` (:func:`pose_corpora`); the other stages read a split
back with :func:`read_corpus_split`, checked against the rig.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from rigmap.animation.corpus import Corpus
from rigmap.errors import RigmapError
from rigmap.store import Layout
from rigmap.store.layout import SPLITS

Log = Callable[[str], None]


class NoMotionLibraryError(RigmapError, KeyError):
    """The rig has no motion library, so no corpus can be played for it."""


def require_motion_library(rig_name: str):
    """The rig's motion library; a rig without one is a :class:`NoMotionLibraryError`."""
    from rigmap.animation.library import motion_library

    try:
        return motion_library(rig_name)
    except KeyError as error:
        raise NoMotionLibraryError(error.args[0] if error.args else str(error)) from None


def read_corpus_split(rig, layout: Layout, split: str) -> Corpus:
    """The rig's corpus of ``split``, checked against the rig's name and used controls."""
    return Corpus.read(
        layout.corpus(rig.name, split), rig=rig.name, control_names=rig.used_controls, split=split
    )


def write_corpora(
    rig, layout: Layout, *, seed: int, fps: int, variation: float = 1.0, log: Log = print
) -> list[Path]:
    """Play the rig's motion library into its train and test corpora (same seed, same bytes).

    ``variation`` scales the seeded timing/value variation of the clips (0 = nominal).
    """
    from rigmap.animation.library import Variation, build_corpus

    require_motion_library(rig.name)  # a rig without clips fails here, before any file is written
    scaled = Variation().scaled(float(variation))
    written = []
    for split in SPLITS:
        corpus = build_corpus(rig, split, seed=int(seed), fps=int(fps), variation=scaled)
        written.append(corpus.write(layout.corpus(rig.name, split)))
        meta = corpus.metadata
        log(
            f"{rig.name} {split}: {len(meta['clips'])} clips, {meta['frame_count']} frames at "
            f"{meta['fps']} fps, {meta['keyed_frame_count']} keyed frames -> {written[-1]}"
        )
    return written


def pose_corpora(
    rig, layout: Layout, *, batch_size: int, progress: bool = True, log: Log = print
) -> list[Path]:
    """Evaluate the rig on every frame of its train and test corpora; write their poses."""
    from rigmap.animation.posing import pose_corpus

    written = []
    for split in SPLITS:
        corpus = read_corpus_split(rig, layout, split)
        poses = pose_corpus(
            rig,
            corpus,
            batch_size=int(batch_size),
            progress=progress,
            source=layout.corpus(rig.name, split).as_posix(),
        )
        written.append(poses.write(layout.poses(rig.name, split)))
        frames = len(poses.table)
        log(f"{rig.name} {split}: {frames} frames, {poses.n_joints} joints -> {written[-1]}")
    return written


def write_heldout(
    rig,
    layout: Layout,
    *,
    seed: int,
    fps: int,
    variation: float,
    batch_size: int,
    heldout_sides: str = "training",
    log: Log = print,
) -> list[Path]:
    """New takes of the training motions and their poses, written together into
    ``data/<rig>/heldout/`` (the in-distribution test set; same seed, same bytes).

    ``heldout_sides``: ``training`` keeps each training take's sides and directions,
    ``drawn`` draws them anew (``rigmap.animation.library.HELDOUT_SIDES``)."""
    from rigmap.animation.library import Variation, build_corpus
    from rigmap.animation.posing import pose_corpus
    from rigmap.store import write_folder_atomic
    from rigmap.store.layout import HELDOUT

    require_motion_library(rig.name)
    scaled = Variation().scaled(float(variation))
    corpus = build_corpus(
        rig, HELDOUT, seed=int(seed), fps=int(fps), variation=scaled, heldout_sides=heldout_sides
    )
    corpus_path, poses_path = layout.corpus(rig.name, HELDOUT), layout.poses(rig.name, HELDOUT)
    poses = pose_corpus(
        rig, corpus, batch_size=int(batch_size), progress=True, source=corpus_path.as_posix()
    )

    def fill(staging: Path) -> None:
        corpus.write(staging / corpus_path.name)
        poses.write(staging / poses_path.name)

    write_folder_atomic(layout.heldout_folder(rig.name), fill)
    meta = corpus.metadata
    log(
        f"{rig.name} {HELDOUT}: {len(meta['clips'])} clips, {meta['frame_count']} frames (the "
        f"training motions at seed {int(seed)} + offset, sides {heldout_sides}) -> {corpus_path}, "
        f"{poses_path}"
    )
    return [corpus_path, poses_path]
