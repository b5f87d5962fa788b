"""The in-distribution test set: new takes of the training motions, scored beside the others."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rigmap.animation.corpus_files import pose_corpora, write_corpora, write_heldout
from rigmap.animation.library import build_corpus
from rigmap.evaluation import TestSet, run_method
from rigmap.evaluation.jobs import set_folder
from rigmap.evaluation.methods import EvaluationSetupError
from rigmap.regression import MeanRegressor
from rigmap.reports.metrics_tree import RigMetrics, _read_splits
from rigmap.reports.settings import ReportSettings
from rigmap.reports.tables import splits_table
from rigmap.store import Layout


def test_heldout_takes_are_the_training_motions_with_other_draws(biped):
    train = build_corpus(biped, "train", seed=0)
    heldout = build_corpus(biped, "heldout", seed=0)
    assert heldout.split == "heldout"
    assert list(dict.fromkeys(heldout.table["clip"])) == list(dict.fromkeys(train.table["clip"]))
    tables = (train.table, heldout.table)
    walk = [t[t["clip"] == "Walk"][biped.used_controls].to_numpy() for t in tables]
    n = min(len(walk[0]), len(walk[1]))
    assert np.abs(walk[0][:n] - walk[1][:n]).max() > 1e-3  # another take, not a copy
    again = build_corpus(biped, "heldout", seed=0)
    pd.testing.assert_frame_equal(again.table, heldout.table)  # seeded: the same bytes


def test_layout_keeps_heldout_files_out_of_the_animate_and_pose_folders():
    layout = Layout(data="d")
    assert layout.corpus("biped", "heldout").as_posix() == "d/biped/heldout/corpus.parquet"
    assert layout.poses("biped", "heldout").as_posix() == "d/biped/heldout/poses.parquet"
    assert layout.corpus("biped", "test").as_posix() == "d/biped/corpus/test.parquet"
    with pytest.raises(ValueError, match="not one of train, test, heldout"):
        layout.corpus("biped", "validation")
    assert set_folder("methods", "heldout") == "methods_heldout"
    assert set_folder("methods", "test") == "methods"
    with pytest.raises(EvaluationSetupError, match=r"evaluate\.test_split"):
        set_folder("methods", "valid")


def test_heldout_and_train_splits_score_and_tabulate(tmp_path, quadruped):
    rig = quadruped
    layout = Layout(data=tmp_path / "data", metrics=tmp_path / "metrics")
    write_corpora(rig, layout, seed=0, fps=24, log=lambda _: None)
    pose_corpora(rig, layout, batch_size=256, progress=False, log=lambda _: None)
    written = write_heldout(rig, layout, seed=0, fps=24, variation=1.0, batch_size=256,
                            log=lambda _: None)  # fmt: skip
    assert [p.name for p in written] == ["corpus.parquet", "poses.parquet"]
    assert sorted(p.name for p in layout.heldout_folder("quadruped").iterdir()) == [
        "corpus.parquet", "poses.parquet",
    ]  # fmt: skip
    train = TestSet.load(rig, layout, split="train")
    X = train.train_poses
    Y = np.concatenate([c.controls for c in train.clips])
    mean = MeanRegressor().fit(X, Y, rig_name="quadruped", control_names=rig.used_controls)
    errors = {}
    for split in ("train", "heldout"):
        test_set = TestSet.load(rig, layout, split=split)
        result = run_method(rig, "mean", test_set, regressor=mean).result
        result.write_json(
            layout.metrics_folder("quadruped", set_folder("methods", split)) / "mean-none.json"
        )
        errors[split] = result.joint_error
    splits = _read_splits(layout.metrics / "quadruped", "quadruped")
    metrics = RigMetrics("quadruped", ())
    metrics.splits = splits
    table = splits_table(
        {"quadruped": metrics}, ReportSettings(rigs=("quadruped",), method_rigs=("quadruped",))
    )
    row = table.data.set_index("method").loc["mean"]
    assert row["train_joint_error"] == pytest.approx(errors["train"])
    assert row["heldout_over_train_joint_error"] == pytest.approx(
        errors["heldout"] / errors["train"]
    )
    assert row["test_joint_error"] is None  # no test-clip file in this tree: left blank
