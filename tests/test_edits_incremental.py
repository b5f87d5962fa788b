"""Incremental refinement (002 §3, Fig 2) on real biped clips: fixes join, refit, suggest."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import rigmap.rigs
from rigmap.edits.incremental import Refinement, refinement_rounds
from rigmap.edits.mirror import subject_mirror
from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import EditModel
from rigmap.edits.representation import ChannelScale, TargetError
from rigmap.edits.subjects import rig_clip, rig_subject

EDITS = Path(__file__).resolve().parents[1] / "conf/edit"


@pytest.fixture(scope="module")
def setup():
    rig = rigmap.rigs.load("biped")
    subject = rig_subject(rig)
    clips = {(name, seed): rig_clip(rig, subject.channels, name, seed)
             for name in ("Walk", "Idle", "Wave") for seed in (0, 1)}  # fmt: skip
    config = yaml.safe_load((EDITS / "arm_swing.yaml").read_text())
    edit = Edit.from_config("arm_swing", config, "rig")
    scale = ChannelScale.fit(list(clips.values()))
    examples = [(subject.source(clips[("Walk", 0)]), edit.apply(clips[("Walk", 0)]))]
    heldout = [subject.source(clips[(name, 1)]) for name in ("Walk", "Idle", "Wave")]
    truths = [edit.apply(s.track) for s in heldout]
    return subject, scale, examples, heldout, truths


def test_fixed_frames_are_learned_and_the_suggestion_is_the_most_uncertain(setup):
    subject, scale, examples, heldout, truths = setup
    refinement = Refinement(EditModel(subject.joints, residual=True), scale, examples,
                            subject_mirror(subject))  # fmt: skip
    model = refinement.fit()
    wave, truth = heldout[2], truths[2]
    before = np.abs(scale.scaled(model.apply(wave)) - scale.scaled(truth))[20:32].mean()
    [pick] = refinement.suggest(heldout, count=1, segment=12)
    variances = [model.predict(s)[0].variance for s in heldout]
    assert pick.variance == pytest.approx(max(v.max() for v in variances))
    assert pick.stop - pick.start == 12
    refinement.add(2, wave, truth, 20, 32)
    assert refinement.fixed[2][2].sum() == 12
    model = refinement.fit()
    assert model.kinematic_gp_.X_.shape[0] == 2 * (examples[0][0].track.n_frames + 12)  # mirrored
    after = np.abs(scale.scaled(model.apply(wave)) - scale.scaled(truth))[20:32].mean()
    assert after < 0.2 * before
    later = refinement.suggest(heldout, count=3, segment=12)
    assert all(not (p.clip == 2 and p.start < 32 and p.stop > 20) for p in later)
    with pytest.raises(TargetError, match="frames 80:200 are not within"):
        refinement.add(2, wave, truth, 80, 200)


def test_rounds_of_suggested_fixes_lower_the_edit_error(setup):
    subject, scale, examples, heldout, truths = setup
    rows = refinement_rounds(EditModel(subject.joints, residual=True), scale, examples,
                             heldout, truths, rounds=2, per_round=2, segment=8)  # fmt: skip
    authored = [r["frames_authored"] for r in rows]
    assert authored[:2] == [0, 16] and 16 < authored[2] <= 32
    assert rows[-1]["edit_error_std"] < 0.7 * rows[0]["edit_error_std"]
    with pytest.raises(TargetError, match="choice must be"):
        refinement_rounds(EditModel(subject.joints), scale, examples, heldout, truths,
                          choice="best")  # fmt: skip


def test_the_cli_plays_refinement_rounds(tmp_path, capsys):
    from rigmap.cli import main

    root = Path(__file__).resolve().parents[1]
    paths = [f"paths.{k}={tmp_path / k}" for k in ("models", "data", "metrics")]
    chosen = ["edits.run=[biped]", "edits.names=[arm_swing]", "+edits.refine.rounds=1",
              "+edits.refine.per_round=1", "+edits.mirror=true", *paths]  # fmt: skip
    assert main(["edits", "add", "--config-dir", str(root / "conf"), *chosen]) == 0
    folder = tmp_path / "metrics/biped/edits/refinement"
    report = yaml.safe_load((folder / "arm_swing.json").read_text())
    assert [r["frames_authored"] for r in report["variance"]] == [0, 12]
    assert [r["round"] for r in report["random"]] == [0, 1]
    assert report["settings"]["rounds"] == 1
    assert (folder / "arm_swing.csv").read_text().startswith("choice,round,frames_authored")
    assert "refinement" in capsys.readouterr().out
