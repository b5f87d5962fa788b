"""map_partial on the biped's real corpus: feet-only and effector input beside full input
(Figs 5, 6), and a joint-space edit mapped back (Fig. 7)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from rigmap.animation.corpus_files import pose_corpora, write_corpora
from rigmap.app.map_partial import (
    MapPartialConfigError,
    _subsets,
    clip_world,
    map_partial,
    read_training,
)
from rigmap.map.clip import MapSettings
from rigmap.map.motion_edit import MotionEdit, descendants, map_edit
from rigmap.map.partial import JointSubset
from rigmap.map.partial_evaluation import PartialInputSettings
from rigmap.regression import GaussianProcessRegressor
from rigmap.regression.kernels import MultiquadricKernel
from rigmap.store import Layout

SUBSETS = {
    "feet": {"joints": ["foot_l", "foot_r", "toe_l", "toe_r"], "origin": "foot_l",
             "left": "foot_l", "right": "foot_r"},
    "effectors": {"joints": ["pelvis", "spine_chest", "head", "hand_l", "hand_r", "foot_l",
                             "foot_r"], "origin": "pelvis", "left": "foot_l", "right": "foot_r"},
}  # fmt: skip
EDIT = MotionEdit(("foot_l", "foot_r"), "hand_r")


def gpr():
    return GaussianProcessRegressor(MultiquadricKernel(), n_points=150, n_length_scales=5,
                                    cv_splits=2, progress=False)  # fmt: skip


@pytest.fixture(scope="module")
def layout(biped, tmp_path_factory):
    layout = Layout(data=tmp_path_factory.mktemp("data"), metrics=tmp_path_factory.mktemp("m"))
    write_corpora(biped, layout, seed=0, fps=24, log=lambda _: None)
    pose_corpora(biped, layout, batch_size=512, progress=False, log=lambda _: None)
    return layout


@pytest.fixture(scope="module")
def written(biped, layout):
    subsets = {n: JointSubset.from_mapping(d, name=n, rig=biped) for n, d in SUBSETS.items()}
    settings = PartialInputSettings(refine_iterations=2, refine_every=16)
    return map_partial(biped, layout, subsets, gpr, settings, EDIT, edit_clip="Walk",
                       edit_frames=24)  # fmt: skip


def test_partial_input_table_holds_every_subset_beside_full_input(written):
    json_file, csv_file, _ = written
    assert json_file.parent.name == "map_partial" and json_file.parent.parent.name == "biped"
    record = json.loads(json_file.read_text())
    table = pd.read_csv(csv_file)
    assert list(table["subset"]) == ["full", "full", "feet", "feet", "effectors", "effectors"]
    assert list(table["stage"]) == ["guess", "refined"] * 3
    assert list(table["given_joints"]) == [73, 73, 4, 4, 7, 7]
    assert record["test_frames"] == 314 and table["frames"].iloc[0] == 314
    np.testing.assert_allclose(table["body_error_cm"], [r["body_error_cm"] for r in record["rows"]],
                               rtol=1e-5)  # fmt: skip
    rows = table.set_index(["subset", "stage"])
    # the full input's given joints are the whole body
    assert rows.loc[("full", "guess"), "given_error_cm"] == pytest.approx(
        rows.loc[("full", "guess"), "body_error_cm"], rel=1e-6)  # fmt: skip
    for subset in ("feet", "effectors"):
        guess, refined = rows.loc[(subset, "guess")], rows.loc[(subset, "refined")]
        assert guess["given_error_cm"] < guess["body_error_cm"]  # a few joints pin only themselves
        assert refined["given_error_cm"] < 0.7 * guess["given_error_cm"]
    # fewer input joints leave more of the body to the corpus
    assert rows.loc[("feet", "guess"), "body_error_cm"] > rows.loc[("full", "guess"),
                                                                     "body_error_cm"]  # fmt: skip


def test_motion_edit_record_says_the_rig_follows_the_edit(written):
    record = json.loads(written[2].read_text())
    assert record["clip"] == "Walk" and record["frames"] == 24
    assert record["foot_height_rms_cm"] < 1.5 and record["foot_height_error_cm"] < 4.0
    assert record["hand_offset_error_cm"] < 2.0


def test_edit_lifts_feet_onto_the_terrain_and_offsets_the_hand_only_in_its_window(biped, layout):
    _, poses = read_training(biped, layout)
    world = clip_world(poses, "Walk", 30)
    edited = EDIT.apply(world, biped)
    names = list(biped.joint_names)
    foot = names.index("foot_l")
    lift = EDIT.terrain(world[:, foot, 0], world[:, foot, 2])
    for joint in ("foot_l", "ball_l", "toe_l"):  # the foot rises rigidly with its ankle
        j = names.index(joint)
        np.testing.assert_allclose(edited[:, j, 1] - world[:, j, 1], lift, atol=1e-12)
    assert np.abs(lift).max() > 1.0  # the walk crosses the terrain's bumps
    hand = [names.index("hand_r"), *descendants(biped, "hand_r")]
    assert {names[i] for i in hand} >= {"middle_tip_r", "thumb_1_r"}
    window = EDIT.hand_window(30)
    assert window[0] == window[-1] == 0.0 and window.max() > 0.95
    feet = [names.index(j) for j in ("foot_l", "ball_l", "toe_l", "foot_r", "ball_r", "toe_r")]
    body = np.setdiff1d(np.arange(len(names)), feet + hand)
    np.testing.assert_allclose(
        edited[:, body][..., [0, 2]], world[:, body][..., [0, 2]], atol=1e-12
    )
    moved = edited[:, hand] - world[:, hand]
    np.testing.assert_allclose(
        moved[:, :, 2], np.repeat(window[:, None] * 8.0, len(hand), 1), atol=1e-12
    )


def test_mapped_back_edit_follows_the_terrain(biped, layout):
    from rigmap.map.partial_evaluation import fit_subset_mappings

    training, poses = read_training(biped, layout)
    world = clip_world(poses, "Walk", 24)
    fitted = fit_subset_mappings(biped, {"feet": JointSubset.from_mapping(
        SUBSETS["feet"], name="feet", rig=biped)}, training, gpr)  # fmt: skip
    result = map_edit(biped, fitted["full"][0], world, EDIT, MapSettings(refine_iterations=3),
                      control_std=training.std, hold_values=training.median)  # fmt: skip
    feet = [biped.joint_names.index(f) for f in EDIT.feet]
    lift = result.edited[:, feet, 1] - result.original[:, feet, 1]
    followed = result.mapped[:, feet, 1] - result.original[:, feet, 1]
    assert np.sqrt((lift**2).mean()) > 2.0  # the edit is cm, not mm
    assert np.sqrt(((followed - lift) ** 2).mean()) < 1.5  # cm: the rig's feet ride the terrain
    assert result.foot_height_rms_cm < 1.5
    with pytest.raises(ValueError, match="every joint"):
        map_edit(biped, fitted["feet"][0], world, EDIT, MapSettings(), control_std=training.std,
                 hold_values=training.median)  # fmt: skip


def test_config_errors_name_the_rig_and_the_subsets(biped):
    with pytest.raises(MapPartialConfigError, match=r"\['hands'\]; rig 'biped' has subsets"):
        _subsets(biped, {"input_joints": ["feet", "hands"], "subsets": {"biped": SUBSETS}})
    with pytest.raises(MapPartialConfigError, match="no entry for rig 'biped'"):
        _subsets(biped, {"input_joints": ["feet"], "subsets": {"quadruped": SUBSETS}})
