"""Moving least squares (002 §4.4) behind the GP's interface, on real biped clips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import rigmap.rigs
from rigmap.edits.gp import GPInputError
from rigmap.edits.mls import MovingLeastSquares
from rigmap.edits.procedural import Edit
from rigmap.edits.propagation import EditModel, load_model, save_model
from rigmap.edits.representation import ChannelScale, TargetError
from rigmap.edits.scoring import score_clip
from rigmap.edits.subjects import rig_clip, rig_subject

EDITS = Path(__file__).resolve().parents[1] / "conf/edit"


@pytest.fixture(scope="module")
def biped():
    rig = rigmap.rigs.load("biped")
    subject = rig_subject(rig)
    clips = {
        (name, seed): rig_clip(rig, subject.channels, name, seed)
        for name in ("Walk", "Idle", "Wave")
        for seed in (0, 1)
    }
    return subject, clips


def test_mls_carries_arms_forward_to_a_held_out_walk_and_is_unsure_off_the_examples(
    biped, tmp_path
):
    subject, clips = biped
    scale = ChannelScale.fit(list(clips.values()))
    config = yaml.safe_load((EDITS / "arms_forward_walking.yaml").read_text())
    forward = Edit.from_config("arms_forward_walking", config, "rig")
    train = [subject.source(clips[(name, 0)]) for name in ("Walk", "Idle")]
    pairs = [(s, forward.apply(s.track)) for s in train]
    model = EditModel(subject.joints, residual=True, estimator="mls").fit(pairs, scale)
    assert isinstance(model.kinematic_gp_, MovingLeastSquares)
    walk = clips[("Walk", 1)]
    result = model.apply(subject.source(walk))
    scores = score_clip(walk, forward.apply(walk), result, scale, subject.relative_cm).summary()
    assert scores["transfer"] > 0.8
    assert scores["joint_rmse_cm"] < 0.3 * scores["source_joint_rmse_cm"]
    # confidence: the held-out walk is nearer the examples than a wave never seen
    k_walk, _ = model.predict(subject.source(walk))
    k_wave, _ = model.predict(subject.source(clips[("Wave", 1)]))
    assert np.median(k_wave.variance) > 3 * np.median(k_walk.variance)
    save_model(model, tmp_path / "mls.npz")
    again = load_model(tmp_path / "mls.npz")
    assert again.estimator == "mls"
    np.testing.assert_allclose(again.apply(subject.source(walk)).values, result.values, atol=1e-9)


def test_mls_reproduces_an_affine_map_and_names_bad_input():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(200, 5))
    Y = X @ rng.normal(size=(5, 3)) + 0.5
    mls = MovingLeastSquares(components=5).fit(X, Y)
    np.testing.assert_allclose(mls.predict(X[:20]).mean, Y[:20], atol=1e-4)
    far = mls.predict(X[:3] + 100.0)
    assert np.isfinite(far.variance).all() and (far.variance > 1e15 * mls.sigma2_).all()
    with pytest.raises(GPInputError, match="column 2"):
        MovingLeastSquares().fit(np.where(np.eye(20, 4, 2) > 0, np.nan, 1.0), np.ones((20, 1)))
    with pytest.raises(TargetError, match="unknown edit estimator 'knn'"):
        EditModel(None, estimator="knn")
