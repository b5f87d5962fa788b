"""Labelled sets from captured takes: a label file of Live Link Face takes on a rig whose
controls are ARKit's (the ARKit face), for latent synthesis on real curves (issue #41).

The label file (:mod:`rigmap.latent.segment_labels`) names segments of the takes per label;
each segment's tracked stretches are takes of that label, valued on the rig's used
controls (:func:`rigmap.latent.live_link.live_link_columns`). Held-out frames come from the
same segments, never from the frames a model learns: each take's last quarter is held out
and the rest trains (ours). A label keeps at most ``CAPTURED_FRAMES[size]`` frames of each
side, takes in the file's order, so a 52-minute label does not make a 52-minute GPLVM (the
quick library's ~150 training frames a label, the paper-size one's ~400, ours).
"""

from __future__ import annotations

from pathlib import Path

from rigmap.latent.errors import LatentInputError
from rigmap.latent.library import LabelledSet, Take, labelled_sets
from rigmap.latent.live_link import live_link_columns
from rigmap.latent.segment_labels import labelled_takes, read_labels

#: frames a label keeps: (training, held out) per size (ours)
CAPTURED_FRAMES: dict[str, tuple[int, int]] = {"quick": (150, 60), "paper": (400, 120)}
HELDOUT_SHARE = 0.25  # ours: each take's last quarter is held out
MIN_HELDOUT_FRAMES = 12  # ours: a label's held-out frames together (0.4 s at 30 fps)
MIN_PIECE_FRAMES = 3  # ours: a shorter piece of a take has no velocity and acceleration


def captured_sets(
    rig,
    label_file: str | Path,
    *,
    fps: float,
    size: str = "quick",
    labels=None,
    heldout: bool = False,
) -> dict[str, LabelledSet]:
    """The label file's labels as training (or held-out) sets of ``rig``'s used controls.

    ``fps`` is the rate the stages assume; the label file's own rate must equal it.
    """
    if size not in CAPTURED_FRAMES:
        raise LatentInputError(f"size must be one of {list(CAPTURED_FRAMES)}, got {size!r}")
    file = read_labels(label_file)
    if abs(file.fps - float(fps)) > 1e-9:
        raise LatentInputError(
            f"{file.path}: its takes are resampled to {file.fps:g} fps, but the latent stages "
            f"run {rig.name!r} at {float(fps):g} fps (latent.{rig.name}_fps)"
        )
    used = [rig.control_names[i] for i in rig.controls.used_indices]
    takes = labelled_takes(file, names=live_link_columns(used))
    chosen = file.labels if labels is None else [str(label) for label in labels]
    unknown = [label for label in chosen if label not in file.labels]
    if unknown:
        raise LatentInputError(f"{file.path}: no label {unknown}; labels: {file.labels}")
    budget = CAPTURED_FRAMES[size][1 if heldout else 0]
    kept: list[Take] = []
    for label in chosen:
        left = budget
        for take in (t for t in takes if t.label == label):
            piece = _split(take.values, heldout)[:left]
            if len(piece) < MIN_PIECE_FRAMES:
                continue
            name = f"{take.name} {'held out' if heldout else 'train'}"
            kept.append(Take(label, name, piece))
            left -= len(piece)
            if left <= 0:
                break
    return labelled_sets(
        kept,
        n_controls=len(used),
        **({"min_frames": MIN_HELDOUT_FRAMES} if heldout else {}),
    )


def _split(values, heldout: bool):
    """A take's first three quarters (training) or its last quarter (held out)."""
    cut = len(values) - max(1, round(HELDOUT_SHARE * len(values)))
    return values[cut:] if heldout else values[:cut]
