"""Incremental refinement (002 §3, Fig 2) on real biped clips: fixes join, refit, suggest."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import rigmap.rigs
from rigmap.edits.incremental import (
    Refinement,
    _pick,
    compare_choices,
    refinement_rounds,
    summarise_rounds,
)
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
    clips = {
        (name, seed): rig_clip(rig, subject.channels, name, seed)
        for name in ("Walk", "Idle", "Wave")
        for seed in (0, 1)
    }
    config = yaml.safe_load((EDITS / "arm_swing.yaml").read_text())
    edit = Edit.from_config("arm_swing", config, "rig")
    scale = ChannelScale.fit(list(clips.values()))
    examples = [(subject.source(clips[("Walk", 0)]), edit.apply(clips[("Walk", 0)]))]
    heldout = [subject.source(clips[(name, 1)]) for name in ("Walk", "Idle", "Wave")]
    truths = [edit.apply(s.track) for s in heldout]
    return subject, scale, examples, heldout, truths


def test_fixed_frames_are_learned_and_the_suggestion_is_the_most_uncertain(setup):
    subject, scale, examples, heldout, truths = setup
    refinement = Refinement(
        EditModel(subject.joints, residual=True), scale, examples, subject_mirror(subject)
    )
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
    rows = refinement_rounds(
        EditModel(subject.joints, residual=True),
        scale,
        examples,
        heldout,
        truths,
        rounds=2,
        per_round=2,
        segment=8,
    )
    authored = [r["frames_authored"] for r in rows]
    assert authored[:2] == [0, 16] and 16 < authored[2] <= 32
    assert rows[-1]["edit_error_std"] < 0.7 * rows[0]["edit_error_std"]
    with pytest.raises(TargetError, match="choice must be"):
        refinement_rounds(
            EditModel(subject.joints), scale, examples, heldout, truths, choice="best"
        )


def test_random_is_played_over_seeds_and_summarised_round_by_round(setup):
    subject, scale, examples, heldout, truths = setup
    report = compare_choices(
        lambda: EditModel(subject.joints, residual=True),
        scale,
        examples,
        heldout,
        truths,
        choices=("variance", "variance_clips"),
        random_seeds=3,
        seed=4,
        rounds=1,
        per_round=1,
        segment=8,
    )
    runs = report["random"]
    assert sorted(runs) == ["4", "5", "6"]
    assert len({run[1]["fixed"] for run in runs.values()}) > 1  # the seeds fix other frames
    errors = np.array([run[1]["edit_error_std"] for run in runs.values()])
    assert len(set(errors)) > 1
    [first, second] = report["summary"]
    assert first["random_std"] == pytest.approx(0.0, abs=1e-12)
    assert first["variance"] == pytest.approx(first["random_mean"])
    assert second["random_mean"] == pytest.approx(errors.mean())
    assert second["random_std"] == pytest.approx(errors.std(ddof=1))
    assert second["random_median"] == pytest.approx(np.median(errors))
    assert (second["random_min"], second["random_max"]) == (errors.min(), errors.max())
    assert second["variance"] == report["variance"][1]["edit_error_std"]
    assert second["variance_below_random"] == int((errors > second["variance"]).sum())
    assert second["variance_frames"] == 8 and second["random_frames_mean"] == 8
    with pytest.raises(TargetError, match="random_seeds"):
        compare_choices(lambda: None, scale, examples, heldout, truths, random_seeds=0)


def test_summary_counts_the_seeds_a_choice_is_below():
    def rows(*errors):
        return [{"frames_authored": 12 * k, "edit_error_std": e} for k, e in enumerate(errors)]

    chosen = {"variance": rows(1.0, 0.25)}
    random = {"0": rows(1.0, 0.2), "1": rows(1.0, 0.3), "2": rows(1.0, 0.4)}
    [_, last] = summarise_rounds(chosen, random)
    assert last["random_mean"] == pytest.approx(0.3)
    assert last["random_std"] == pytest.approx(0.1)
    assert last["random_median"] == pytest.approx(0.3)
    assert (last["random_min"], last["random_max"]) == (0.2, 0.4)
    assert last["variance_below_random"] == 2


def test_variance_clips_spreads_the_highest_variance_picks_over_clips():
    variances = [np.full(40, 2.0), np.linspace(0.0, 1.0, 30), np.full(20, 0.5)]
    plain = _pick(variances, {}, 2, 8)
    assert [p.clip for p in plain] == [0, 0]  # a flat novel clip takes both
    spread = _pick(variances, {}, 3, 8, per_clip=True)
    assert [p.clip for p in spread] == [0, 1, 2]
    assert (spread[1].start, spread[1].stop, spread[1].variance) == (22, 30, 1.0)
    fixed = {0: (None, None, np.arange(40) < 8)}  # clip 0 had a segment: the others first
    assert [p.clip for p in _pick(variances, fixed, 2, 8, per_clip=True)] == [1, 2]


def test_the_cli_plays_refinement_rounds(tmp_path, capsys):
    from rigmap.cli import main

    root = Path(__file__).resolve().parents[1]
    paths = [f"paths.{k}={tmp_path / k}" for k in ("models", "data", "metrics")]
    chosen = [
        "edits.run=[biped]",
        "edits.names=[arm_swing]",
        "+edits.refine.rounds=1",
        "+edits.refine.per_round=1",
        "+edits.refine.random_seeds=2",
        "+edits.mirror=true",
        *paths,
    ]
    assert main(["edits", "add", "--config-dir", str(root / "conf"), *chosen]) == 0
    folder = tmp_path / "metrics/biped/edits/refinement"
    report = yaml.safe_load((folder / "arm_swing.json").read_text())
    assert [r["frames_authored"] for r in report["variance"]] == [0, 12]
    assert sorted(report["random"]) == ["0", "1"]
    assert [r["round"] for r in report["random"]["1"]] == [0, 1]
    assert [r["round"] for r in report["summary"]] == [0, 1]
    assert report["settings"]["rounds"] == 1 and report["settings"]["random_seeds"] == 2
    assert (folder / "arm_swing.csv").read_text().startswith("choice,seed,round,frames_authored")
    assert (folder / "arm_swing_summary.csv").read_text().startswith("round,variance_frames")
    assert "refinement" in capsys.readouterr().out


def test_refinement_settings_are_checked_before_any_work():
    from rigmap.edits.steps import REFINE_DEFAULTS, refine_settings

    assert refine_settings({}) == REFINE_DEFAULTS
    assert refine_settings({"refine": {"rounds": 2}})["rounds"] == 2
    with pytest.raises(TargetError, match=r"edits.refine: unknown setting\(s\) \['round'\]"):
        refine_settings({"refine": {"round": 2}})  # a typo is not silently ignored
    with pytest.raises(TargetError, match=r"edits.refine.random_seeds must be an integer"):
        refine_settings({"refine": {"random_seeds": [0, 1]}})  # a count, not a list of seeds
    with pytest.raises(TargetError, match=r"edits.refine.choices must be a list"):
        refine_settings({"refine": {"choices": "variance"}})
