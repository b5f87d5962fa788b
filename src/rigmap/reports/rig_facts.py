"""The numbers of Table 3: training frames, rig DOFs and joint DOFs of each character.

Training frames count every played frame of the train corpus (keys and the
frames interpolated between them, as the paper's data set), keyed frames are
reported beside them. Rig DOFs are all the rig's controls, with the used ones
(those the animators key, §6.1) beside them; joint DOFs are 3 × joints (or
mesh vertices). A Blender rig's controls are every transform channel of its
control bones and every custom property; its joints the deform bones its config
selects.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rigmap.animation.corpus import Corpus, CorpusError
from rigmap.reports.metrics_tree import ReportInputError


@dataclass(frozen=True)
class RigFacts:
    rig: str
    training_frames: int
    keyed_frames: int
    rig_dofs: int
    used_rig_dofs: int
    joint_dofs: int
    length_unit: str
    backend: str = "built-in"  # "blender" for a rig evaluated by Blender workers


def rig_facts(rig, train_corpus: str | Path) -> RigFacts:
    """Table 3's numbers for ``rig`` and its train corpus file."""
    train_corpus = Path(train_corpus)
    if not train_corpus.is_file():
        raise ReportInputError(
            f"{train_corpus}: train corpus missing (the animate stage writes it); Table 3 "
            f"counts rig {rig.name!r}'s training frames from it"
        )
    try:
        corpus = Corpus.read(
            train_corpus, rig=rig.name, control_names=rig.used_controls, split="train"
        )
    except CorpusError as error:
        raise ReportInputError(f"{train_corpus}: {error}") from None
    metadata = corpus.metadata
    return RigFacts(
        rig=rig.name,
        training_frames=len(corpus.table),
        keyed_frames=int(metadata.get("keyed_frame_count", 0)),
        rig_dofs=len(rig.control_names),
        used_rig_dofs=len(rig.used_controls),
        joint_dofs=3 * int(rig.n_joints),
        length_unit=str(getattr(rig, "length_unit", "cm")),
        backend="blender" if getattr(rig, "blender_version", None) else "built-in",
    )
