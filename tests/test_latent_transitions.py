"""Matching points between models, routes through a third model (§5.2) and the
motion-graph baseline (Kovar et al. 2002)."""

from __future__ import annotations

import numpy as np
import pytest

from latent_face import face_models, face_rig, face_transitions
from rigmap.latent import LatentInputError
from rigmap.latent.motion_graph import (
    blend_transition,
    find_transitions,
    kovar_weights,
    largest_component,
    local_minima,
    window_distance,
)
from rigmap.latent.synthesis import Controller, Move, Transition
from rigmap.latent.transitions import blend_weights, match_pair, surface_distance


@pytest.fixture(scope="module")
def fitted():
    return face_models()


def test_matching_points_reproduce_their_distances(fitted):
    """Every kept pair: the two models' poses at its two points are as close as stored
    and under the threshold, and its point in the target is the projection of the
    source's pose (Eq 15: no other point of the target does much better)."""
    table = face_transitions()
    rig = face_rig()
    for (a, b), m in table.matches.items():
        assert m.candidates == len(fitted.sets[a].values) + len(fitted.sets[b].values)
        if len(m) == 0:
            continue
        Pa = fitted.models[a].to_controls(m.source_points)
        Pb = fitted.models[b].to_controls(m.target_points)
        d = surface_distance(rig, Pa, Pb)
        np.testing.assert_allclose(d, m.distance_cm, rtol=1e-6, atol=1e-9)
        assert (d < table.threshold_cm).all()
    # Eq 15 is solved in the target's PCA space: there the projection beats (or ties)
    # every training latent point of the target
    source, target = fitted.models["happy"], fitted.models["neutral"]
    one_way = match_pair(rig, source, target, threshold_cm=1e9)
    y_hat = target.to_pca(source.to_controls(one_way.source_points))
    at_projection = np.linalg.norm(y_hat - target.gplvm.mean(one_way.target_points), axis=1)
    F = target.gplvm.mean(target.latent)
    best_training = np.sqrt(((y_hat[:, None] - F[None]) ** 2).sum(-1)).min(1)
    assert (at_projection <= best_training * (1 + 1e-9) + 1e-12).mean() > 0.95
    assert at_projection.mean() < 0.8 * best_training.mean()


def test_similar_sets_share_more_bridges_than_distinct_ones():
    counts = {k: len(m) for k, m in face_transitions().matches.items()}
    assert counts[("happy", "neutral")] > counts[("happy", "roar")]
    assert counts[("neutral", "roar")] > counts[("happy", "roar")]
    assert counts[("happy", "roar")] == counts[("roar", "happy")]


def test_route_goes_through_a_third_model_when_two_share_no_match():
    table = face_transitions().without("happy", "roar")
    assert len(table.pair("happy", "roar")) == 0
    assert table.route("happy", "roar") == ["happy", "neutral", "roar"]
    cut_off = table.without("neutral", "roar")
    with pytest.raises(LatentInputError, match="no transition from model 'happy' to 'roar'"):
        cut_off.route("happy", "roar")


def test_controller_transitions_through_the_third_model(fitted):
    table = face_transitions().without("happy", "roar")
    c = Controller(fitted.models, start="happy", takes=fitted.sets, transitions=table, seed=1)
    out = c.run([Move(take="happy 0", frame=30), Transition("roar")])
    entry = c.log[-1]
    assert c.model == "roar" and entry.success
    assert len(entry.switches) == 2  # happy → neutral, neutral → roar
    rig = face_rig()
    assert (out >= rig.controls.lower).all() and (out <= rig.controls.upper).all()


def test_blend_weights_rise_smoothly_to_one():
    w = blend_weights(12)
    assert len(w) == 12 and w[-1] == 1.0 and (np.diff(w) > 0).all() and w[0] > 0


# --- the motion graph ---------------------------------------------------------------
def smooth_clip(rng, n, d=5):
    t = np.linspace(0, 1, n)[:, None]
    return np.sin(2 * np.pi * (t * rng.uniform(0.5, 2.0, d) + rng.uniform(0, 1, d)))


def test_motion_graph_finds_a_planted_transition():
    rng = np.random.default_rng(3)
    A = smooth_clip(rng, 90)
    B = smooth_clip(rng, 80) + 2.0  # far from A everywhere ...
    i0, j0, k = 37, 21, 12
    B[j0 : j0 + k] = A[i0 : i0 + k]  # ... but where A's frames were copied in
    D = window_distance(A, B, k)
    assert D.shape == (90 - k + 1, 80 - k + 1)
    minima = local_minima(D, threshold=1e-6)
    assert minima[0][:2] == (i0, j0) and minima[0][2] == pytest.approx(0.0, abs=1e-9)
    found = find_transitions({"a": A, "b": B}, {"a": A, "b": B}, threshold=1e-6)
    assert [(t.source, t.target, t.i, t.j) for t in found] == [
        ("a", "b", i0, j0),
        ("b", "a", j0, i0),
    ]


def test_motion_graph_window_distance_matches_a_direct_sum():
    rng = np.random.default_rng(0)
    A, B = rng.standard_normal((20, 4)), rng.standard_normal((15, 4))
    D = window_distance(A, B, 4)
    i, j = 7, 3
    assert D[i, j] == pytest.approx(((A[i : i + 4] - B[j : j + 4]) ** 2).sum())


def test_motion_graph_blend_runs_from_one_clip_into_the_other():
    A = np.zeros((40, 2))
    B = np.ones((30, 2))
    out, start = blend_transition(A, B, 20, 5, 12)
    assert start == 20 and len(out) == 20 + 12 + (30 - 5 - 12)
    np.testing.assert_array_equal(out[:20], 0.0)
    np.testing.assert_array_equal(out[32:], 1.0)
    np.testing.assert_allclose(out[20:32, 0], 1.0 - kovar_weights(12))
    assert (np.diff(out[20:32, 0]) > 0).all()
    with pytest.raises(LatentInputError):
        blend_transition(A, B, 35, 5, 12)


def test_largest_component_drops_dead_ends():
    """a ⇄ b by two transitions; c is entered from a but never left: not in the SCC."""
    from rigmap.latent.motion_graph import GraphTransition as T

    lengths = {"a": 30, "b": 30, "c": 30}
    transitions = [T("a", "b", 20, 2, 0.0), T("b", "a", 20, 2, 0.0), T("a", "c", 10, 0, 0.0)]
    keep = largest_component(lengths, transitions, window=4)
    assert not keep["c"].any()
    assert keep["a"][6:21].all() and keep["b"][6:21].all()
    assert not keep["a"][-1]  # past the last transition out of a: a dead end
