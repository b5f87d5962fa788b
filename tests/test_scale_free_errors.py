"""Errors a reader can compare across rigs: RMS distance, % of height, ÷ the mean predictor."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rig_poses import random_used_controls
from rigmap.animation.library import build_corpus
from rigmap.error_measures import joint_rms
from rigmap.evaluation import ClipResult, MethodResult, MetricInputError, joint_error
from rigmap.regression import MeanRegressor, ModelMismatchError, load_regressor


def test_joint_rms_is_the_root_mean_squared_joint_distance(biped):
    X = biped.evaluate(random_used_controls(biped, 5, seed=3))
    X_off = biped.evaluate(random_used_controls(biped, 5, seed=4))
    distances = np.linalg.norm(X_off - X, axis=2)  # (frames, joints) cm
    expected = float(np.sqrt((distances**2).mean()))
    assert joint_rms(joint_error(X_off, X).mean) == pytest.approx(expected, rel=1e-12)
    assert expected > 1.0  # the poses differ by centimetres, not a rounding error
    with pytest.raises(MetricInputError, match="expected a mean squared error >= 0"):
        joint_rms(-1.0)


def test_rest_height_is_the_vertical_extent_of_the_default_pose(biped, quadruped):
    for rig in (biped, quadruped):
        rest = rig.pose(rig.controls.defaults[None])
        heights = (np.asarray(rest.positions)[0] + np.asarray(rest.cog)[0])[:, 1]
        assert rig.rest_height() == pytest.approx(heights.max() - heights.min(), rel=1e-12)
    # a biped stands taller than its dog (178.5 and 106.5 cm in the built-in rigs)
    assert biped.rest_height() > quadruped.rest_height() > 50.0


def _result(height):
    clip = ClipResult("walk", np.array([4.0, 12.0]), np.array([1.0, 1.0]), total_time_s=0.5)
    return MethodResult("biped", "gpr", "none", [clip], character_height=height)


def test_metrics_files_state_the_joint_error_as_a_distance_and_a_share_of_height(tmp_path):
    data = json.loads(_result(160.0).write_json(tmp_path / "gpr-none.json").read_text())
    rms = np.sqrt(3 * 8.0)  # mean squared coordinate error 8 cm² -> sqrt(24) cm per joint
    for numbers in (data["average"], data["clips"]["walk"]):
        assert numbers["joint_rms"] == pytest.approx(rms)
        assert numbers["joint_rms_percent_of_height"] == pytest.approx(100 * rms / 160.0)
    assert data["character_height"] == 160.0
    assert "joint_rms_percent_of_height" in data["units"]
    # without a height (a result built by hand) the share is left out, not invented
    assert "joint_rms_percent_of_height" not in _result(None).average()
    with pytest.raises(MetricInputError, match="character_height must be > 0"):
        _result(0.0)


def test_mean_predictor_predicts_the_training_mean_and_reloads(tmp_path, biped):
    corpus = build_corpus(biped, "train", seed=0).table[biped.used_controls]
    Y = corpus.to_numpy(float)[::10]
    X = np.random.default_rng(0).normal(size=(len(Y), 7))
    model = MeanRegressor().fit(X, Y, rig_name="biped", control_names=biped.used_controls)
    predicted = model.predict(X[:3] + 100.0)  # any input: the same average pose
    np.testing.assert_allclose(predicted, np.repeat(Y.mean(0)[None], 3, axis=0), rtol=1e-12)
    model.save(tmp_path / "mean")
    loaded = load_regressor(tmp_path / "mean", rig=biped)
    np.testing.assert_array_equal(loaded.predict(X[:2]), model.predict(X[:2]))
    with pytest.raises(ModelMismatchError):
        load_regressor(tmp_path / "mean", rig="quadruped")
