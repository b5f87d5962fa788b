"""A rig's test clips as the evaluation scores them: target poses, ground truth, scales."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.metrics import control_std
from rigmap.store import Layout


@dataclass(frozen=True)
class TestClip:
    """One test clip: target poses (cm, COG-relative, COG placement) and the animator's keys."""

    name: str
    frames: np.ndarray  # (N,) the clip's frame numbers
    positions: np.ndarray  # (N, J, 3)
    cog: np.ndarray  # (N, 3)
    cog_rotation: np.ndarray  # (N, 3, 3)
    controls: np.ndarray  # (N, C_used) the animator's values = ground truth

    __test__ = False  # a data class, not a pytest test class

    def __len__(self) -> int:
        return len(self.frames)


@dataclass(frozen=True)
class TestSet:
    """A rig's test clips and the training-corpus std that scales the ground-truth error."""

    rig: str
    clips: list[TestClip]
    control_names: list[str]  # the used controls, rig order
    control_kinds: list[str]
    train_std: np.ndarray  # (C_used,)
    character_height: float | None = None  # the rig's rest height; errors as % of it
    train_poses: np.ndarray | None = None  # (N, 3J + 12) pose rows a fit on the corpus learns
    train_controls: np.ndarray | None = None  # (N, C_used): their controls, row for row

    __test__ = False  # a data class, not a pytest test class

    @property
    def frames(self) -> int:
        return sum(len(c) for c in self.clips)

    def first_frames(self, n: int | None) -> TestSet:
        """The same clips cut to their first ``n`` frames (``None``: unchanged)."""
        if n is None:
            return self
        if int(n) != n or n < 1:
            raise EvaluationSetupError(f"frames per clip: expected an integer >= 1, got {n!r}")
        n = int(n)
        clips = [
            TestClip(
                c.name, c.frames[:n], c.positions[:n], c.cog[:n], c.cog_rotation[:n], c.controls[:n]
            )
            for c in self.clips
        ]
        return TestSet(
            self.rig,
            clips,
            self.control_names,
            self.control_kinds,
            self.train_std,
            self.character_height,
            self.train_poses,
            self.train_controls,
        )

    @classmethod
    def load(
        cls,
        rig: Any,
        data: Layout | str | Path,
        *,
        clips: Sequence[str] | None = None,
        split: str = "test",
    ) -> TestSet:
        """Read the rig's poses and corpus of ``split`` and its training corpus.

        ``data`` is a :class:`rigmap.store.Layout` or the rig's data folder
        (``data/<rig>``); ``clips`` picks clips by name (default: all, in file order);
        ``split`` is ``test`` (the library's test clips), ``heldout`` (new takes of the
        training motions) or ``train`` (the training frames: the training error).
        """
        from rigmap.animation.corpus import Corpus
        from rigmap.animation.posing import PoseTable

        layout = _layout_of(data, rig.name)
        used = list(rig.used_controls)
        poses_file, corpus_file = layout.poses(rig.name, split), layout.corpus(rig.name, split)
        poses = PoseTable.read(poses_file, rig=rig.name, n_joints=rig.n_joints, split=split)
        if poses.joint_names != list(rig.joint_names):
            raise EvaluationSetupError(f"{poses_file}: joint names differ from rig {rig.name!r}'s")
        test = Corpus.read(corpus_file, rig=rig.name, control_names=used, split=split)
        train = Corpus.read(
            layout.corpus(rig.name, "train"), rig=rig.name, control_names=used, split="train"
        )
        keys = ["clip", "frame"]
        pose_keys = poses.table[keys].reset_index(drop=True)
        corpus_keys = test.table[keys].reset_index(drop=True)
        if not pose_keys.equals(corpus_keys):
            raise EvaluationSetupError(
                f"{poses_file} and {corpus_file} list different (clip, frame) rows "
                f"({len(pose_keys)} and {len(corpus_keys)} rows); re-run the stage that wrote them"
            )
        names = list(dict.fromkeys(poses.table["clip"]))
        if clips is not None:
            unknown = [c for c in clips if c not in names]
            if unknown or not clips:
                raise EvaluationSetupError(
                    f"{split} clips {unknown or '[]'} not found for rig {rig.name!r}; "
                    f"its {split} clips are {names}"
                )
            names = list(clips)
        positions, cog, rotation = poses.positions(), poses.cog(), poses.cog_rotation()
        truth = test.table[used].to_numpy(dtype=np.float64)
        clip_column = poses.table["clip"].to_numpy()
        frame_column = poses.table["frame"].to_numpy()
        test_clips = []
        for name in names:
            rows = np.flatnonzero(clip_column == name)
            test_clips.append(
                TestClip(
                    name,
                    frame_column[rows].astype(np.int64),
                    positions[rows],
                    cog[rows],
                    rotation[rows],
                    truth[rows],
                )
            )
        kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
        std = control_std(train.table[used].to_numpy(dtype=np.float64))
        train_poses, train_controls = _training_rows(rig, layout)
        return cls(
            rig.name, test_clips, used, kinds, std, rig.rest_height(), train_poses, train_controls
        )


def _training_rows(rig: Any, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """The pose rows and controls a fit on the corpus learns from (the corpus frames and the
    rest pose, as the fit stage reads them): what a test frame's novelty is measured to."""
    from rigmap.regression.fitting import load_training_data

    data = load_training_data(rig, layout.data, "none")
    return data.features, data.controls


def _layout_of(data: Layout | str | Path, rig: str) -> Layout:
    """``data`` as a Layout; a folder must be the rig's own (``<data root>/<rig>``)."""
    if isinstance(data, Layout):
        return data
    folder = Path(data)
    if folder.name != rig:
        raise EvaluationSetupError(
            f"test data folder {folder}: expected the rig's data folder <data>/{rig}, or a Layout"
        )
    return Layout(data=folder.parent)
