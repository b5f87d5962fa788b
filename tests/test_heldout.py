"""The in-distribution test set: new takes of the training motions, scored beside the others."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rigmap.animation.corpus_files import pose_corpora, write_corpora, write_heldout
from rigmap.animation.keyframes import KeyframeError
from rigmap.animation.library import (
    HELDOUT_SEED_OFFSET,
    ClipBuilder,
    build_clip,
    build_corpus,
    clip_rng,
    motion_library,
)
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


def _turn_yaw(clip_table):
    """The biped Turn's last COG yaw: its sign is the way the take turned."""
    return float(clip_table[clip_table["clip"] == "Turn"]["cog.ry"].to_numpy()[-1])


def test_heldout_takes_keep_the_training_takes_sides_unless_drawn(biped):
    train = build_corpus(biped, "train", seed=0).table
    kept = build_corpus(biped, "heldout", seed=0).table
    drawn = build_corpus(biped, "heldout", seed=0, heldout_sides="drawn").table
    # at this seed the held-out draw turns the other way: keeping the sides turns it back
    assert np.sign(_turn_yaw(drawn)) == -np.sign(_turn_yaw(train))
    assert np.sign(_turn_yaw(kept)) == np.sign(_turn_yaw(train))
    assert abs(_turn_yaw(kept)) != pytest.approx(abs(_turn_yaw(train)))  # new take
    # only the sides differ: where the two draws agree on every side, the takes are equal
    same_sides = []
    for name in dict.fromkeys(train["clip"]):
        _, motion = motion_library("biped").find(name)
        probes = [ClipBuilder(name, clip_rng(s, "biped", name)) for s in (0, HELDOUT_SEED_OFFSET)]
        for probe in probes:
            motion.keyframe(probe)
        if probes[0].sides_drawn == probes[1].sides_drawn:
            same_sides.append(name)
            pd.testing.assert_frame_equal(
                kept[kept["clip"] == name].reset_index(drop=True),
                drawn[drawn["clip"] == name].reset_index(drop=True),
            )
    assert "Walk" in same_sides and "Turn" not in same_sides
    with pytest.raises(ValueError, match="heldout_sides must be one of"):
        build_corpus(biped, "heldout", seed=0, heldout_sides="mirrored")


def test_replaying_sides_checks_their_count_and_gives_a_take_back():
    _, turn = motion_library("biped").find("Turn")
    short = ClipBuilder("Turn", clip_rng(0, "biped", "Turn"), sides=[])
    with pytest.raises(KeyframeError, match="asks for side 1 but only 0"):
        turn.keyframe(short)
    long = ClipBuilder("Turn", clip_rng(0, "biped", "Turn"), sides=[1.0, -1.0, 1.0])
    turn.keyframe(long)
    with pytest.raises(KeyframeError, match="3 sides were given to replay but the motion asked"):
        long.build()
    # replaying a take's own sides gives that take back, to the bit
    take = build_clip("biped", turn, seed=0)
    again = build_clip("biped", turn, seed=0, sides_of_seed=0)
    controls = take.controls
    assert again.controls == controls
    zeros = np.zeros(len(controls))
    np.testing.assert_array_equal(again.evaluate(controls, zeros), take.evaluate(controls, zeros))


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
    X, Y = train.train_poses, train.train_controls  # the corpus and the rest pose
    assert len(X) == sum(len(c) for c in train.clips) + 1  # the quadruped's corpus lacks it
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
