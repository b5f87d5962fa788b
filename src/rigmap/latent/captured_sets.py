"""Labelled sets from a user's takes: a label file of Live Link Face takes (the ARKit
face's captured curves), a controls table or a .blend's actions (issue #41).

:func:`rigmap.latent.take_files.read_labelled_takes` reads the file as labelled takes on
the rig's used controls (a Live Link segment's tracked stretches each one take). Held-out
frames come from the
same segments, never from the frames a model learns: each take's last quarter is held out
and the rest trains (ours). A label keeps at most ``CAPTURED_FRAMES[size]`` frames of each
side, takes in the file's order, so a 52-minute label does not make a 52-minute GPLVM (the
quick library's ~150 training frames a label, the paper-size one's ~400, ours).
"""

from __future__ import annotations

from pathlib import Path

from rigmap.latent.errors import LatentInputError
from rigmap.latent.library import LabelledSet, Take, labelled_sets
from rigmap.latent.take_files import MIN_TAKE_FRAMES, read_labelled_takes

#: frames a label keeps: (training, held out) per size (ours)
CAPTURED_FRAMES: dict[str, tuple[int, int]] = {"quick": (150, 60), "paper": (400, 120)}
HELDOUT_SHARE = 0.25  # ours: each take's last quarter is held out
MIN_HELDOUT_FRAMES = 12  # ours: a label's held-out frames together (0.4 s at 30 fps)
MIN_PIECE_FRAMES = 3  # ours: a shorter piece of a take has no velocity and acceleration


def captured_sets(
    rig,
    takes_file: str | Path,
    *,
    fps: float,
    size: str = "quick",
    labels=None,
    heldout: bool = False,
    label_pattern: str | None = None,
) -> dict[str, LabelledSet]:
    """The file's labels as training (or held-out) sets of ``rig``'s used controls.

    ``fps`` is the rate the stages assume; the file's own rate must equal it. A held-out
    piece shorter than ``MIN_PIECE_FRAMES`` (the last quarter of a take under 10 frames)
    is not used: it has no acceleration to measure.
    """
    if size not in CAPTURED_FRAMES:
        raise LatentInputError(f"size must be one of {list(CAPTURED_FRAMES)}, got {size!r}")
    takes = read_labelled_takes(takes_file, rig, fps=fps, label_pattern=label_pattern)
    found = list(dict.fromkeys(t.label for t in takes))
    chosen = found if labels is None else [str(label) for label in labels]
    unknown = [label for label in chosen if label not in found]
    if unknown:
        raise LatentInputError(f"{takes_file}: no label {unknown}; labels: {found}")
    budget = CAPTURED_FRAMES[size][1 if heldout else 0]
    kept: list[Take] = []
    for label in chosen:
        left = budget
        for take in (t for t in takes if t.label == label):
            if len(take.values) < MIN_TAKE_FRAMES + 1:  # its training part needs 3 frames
                raise LatentInputError(
                    f"{takes_file}: take {take.name!r} (label {label!r}) has "
                    f"{len(take.values)} frames; the model needs at least {MIN_TAKE_FRAMES + 1}"
                )
            piece = _split(take.values, heldout)[:left]
            if len(piece) < MIN_PIECE_FRAMES:
                continue
            name = f"{take.name} {'held out' if heldout else 'train'}"
            kept.append(Take(label, name, piece))
            left -= len(piece)
            if left <= 0:
                break
    try:
        return labelled_sets(
            kept,
            n_controls=len(rig.controls.used_indices),
            **({"min_frames": MIN_HELDOUT_FRAMES} if heldout else {}),
        )
    except LatentInputError as error:
        side = "held-out" if heldout else "training"
        raise LatentInputError(f"{takes_file} ({side} frames): {error}") from None


def _split(values, heldout: bool):
    """A take's first three quarters (training) or its last quarter (held out)."""
    cut = len(values) - max(1, round(HELDOUT_SHARE * len(values)))
    return values[cut:] if heldout else values[:cut]
