"""The network trained through the rig: its forward, its gradient, its training, its ranges."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
import torch

from rigmap.error_measures import MetricInputError
from rigmap.evaluation.clips import TestSet
from rigmap.evaluation.novelty import Novelty
from rigmap.evaluation.runner import _novelty_of
from rigmap.regression import JointSpaceNetworkRegressor, load_regressor
from rigmap.regression.errors import ModelFileError
from rigmap.regression.features import inverse_features
from rigmap.regression.joint_space_network import SquashedNetwork, draws_summary, same_draws
from rigmap.regression.joint_space_training import (
    JointSpaceData,
    draw_training_controls,
    joint_space_cost,
    local_draws,
    pose_training_draws,
)
from rigmap.regression.mapping import InverseMapping
from rigmap.regression.placement import find_placement, heading, turn_matrix
from rigmap.regression.rig_forward import NotDifferentiableRigError, PlacedRigForward
from rigmap.rigs import load
from rigmap.rigs.engine.builder import RigBuilder
from rigmap.rigs.engine.torch_rig import TorchRig


def tiny_rig() -> TorchRig:
    """A root that walks and turns, a COG, and a three-segment arm: 8 used controls."""
    b = RigBuilder("tiny")
    b.transform_control("root", parent=None, group="root", used="tx tz ry")
    b.transform_control("cog", parent="root", offset=(0, 50, 0), group="body", used="ty rx")
    b.transform_control("upper", parent="cog", offset=(10, 0, 0), group="arm", used="rz ry")
    b.transform_control("lower", parent="upper", offset=(20, 0, 0), group="arm", used="rz")
    b.transform_control("hand", parent="lower", offset=(20, 0, 0), group="arm")
    for name, parent in (("cog", None), ("upper", "cog"), ("lower", "upper"), ("hand", "lower")):
        b.joint(name, parent)
    return TorchRig(b)


def corpus(rig, n: int, seed: int, spread: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Used controls a fraction into their soft ranges, and their pose rows."""
    rng = np.random.default_rng(seed)
    used = rig.controls.used_indices
    lo, hi = rig.controls.lower[used], rig.controls.upper[used]
    Y = spread * rng.uniform(lo, hi, size=(n, len(used)))
    pose = rig.pose(rig.expand_used(Y))
    X = inverse_features(
        pose.positions, pose.cog, pose.cog_rotation, n_joints=rig.n_joints, where="t"
    )
    return X, Y


@pytest.fixture(scope="module")
def tiny():
    rig = tiny_rig()
    X, Y = corpus(rig, 40, seed=0)
    placement = find_placement(rig, np.concatenate([np.zeros((1, Y.shape[1])), Y[:3]]))
    assert placement.turn is not None and placement.ground is not None
    return rig, placement, X, Y


def heading_frame_pose(rig, placement, targets, X):
    """The numpy path: controls from the placement, the rig, turned into the target's frame."""
    pose = rig.pose(rig.expand_used(placement.controls(targets, X)))
    n3 = 3 * rig.n_joints
    R = turn_matrix(heading(X[:, n3 + 3 :].reshape(-1, 3, 3)))
    joints = np.einsum("nab,nja->njb", R, pose.positions)
    cog = np.einsum("nab,na->nb", R, pose.cog - X[:, n3 : n3 + 3])
    cog[:, 1] = pose.cog[:, 1]
    return joints, cog


@pytest.mark.parametrize("which", ["tiny", "quadruped"])
def test_placed_forward_is_the_rig_behind_the_placement(which, tiny, quadruped):
    if which == "tiny":
        rig, placement, X, Y = tiny
    else:
        rig = quadruped
        X, Y = corpus(rig, 6, seed=3, spread=0.1)
        placement = find_placement(rig, np.concatenate([np.zeros((1, Y.shape[1])), Y[:3]]))
    targets = placement.targets(Y, X) + 0.05 * np.random.default_rng(1).normal(size=Y.shape)
    joints, cog = heading_frame_pose(rig, placement, targets, X)
    placed = PlacedRigForward(rig, placement)(torch.from_numpy(targets))
    np.testing.assert_allclose(placed.joints.numpy(), joints, atol=1e-9)
    np.testing.assert_allclose(placed.cog.numpy(), cog, atol=1e-9)
    # the exact targets give back the pose the inputs hold
    exact = PlacedRigForward(rig, placement)(torch.from_numpy(placement.targets(Y, X)))
    held_joints, held_cog = PlacedRigForward(rig, placement).input_pose(placement.inputs(X))
    np.testing.assert_allclose(exact.joints.numpy(), held_joints, atol=1e-9)
    np.testing.assert_allclose(exact.cog.numpy(), held_cog, atol=1e-9)


def test_joint_space_cost_gradient_matches_finite_differences(tiny):
    rig, placement, X, Y = tiny
    forward = PlacedRigForward(rig, placement)
    inputs, targets = placement.inputs(X), placement.targets(Y, X)
    data = JointSpaceData.build(forward, inputs[:30], targets[:30], inputs[30:], targets[30:], 10)
    for name in ("inputs", "targets", "joints", "target_std", "spread"):
        setattr(data, name, getattr(data, name).double())
    network = SquashedNetwork(
        inputs.shape[1], 16, 2, targets.shape[1], torch.Generator().manual_seed(0)
    )
    bounded = np.ones(targets.shape[1], dtype=bool)
    bounded[[c.index for c in placement.channels]] = False
    used = rig.controls.used_indices
    network.set_scales(
        inputs.mean(0),
        inputs.std(0) + 1e-3,
        rig.controls.lower[used],
        rig.controls.upper[used],
        targets.mean(0),
        targets.std(0),
        bounded,
    )
    network = network.double()
    rows = torch.arange(len(inputs))  # known rows and drawn ones: both terms

    def cost() -> torch.Tensor:
        joint, control = joint_space_cost(network, forward, data, rows)
        return joint + 0.3 * control

    weight = network.layers[0].weight
    network.zero_grad()
    cost().backward()
    analytic = weight.grad.clone()
    step = 1e-6
    for i, j in [(0, 0), (3, 5), (7, 11), (15, 2)]:
        with torch.no_grad():
            weight[i, j] += step
            plus = float(cost())
            weight[i, j] -= 2 * step
            minus = float(cost())
            weight[i, j] += step
        numeric = (plus - minus) / (2 * step)
        assert numeric == pytest.approx(float(analytic[i, j]), rel=1e-5, abs=1e-9)


def fitted(tiny, **params) -> InverseMapping:
    rig, placement, X, Y = tiny
    settings = dict(
        hidden=64,
        layers=2,
        n_gaussian=0,
        n_wide=0,
        pretrain_epochs=0,
        epochs=300,
        batch_size=40,
        control_weight=0.0,
        learning_rate=3e-3,
        progress=False,
    )
    settings.update(params)
    model = JointSpaceNetworkRegressor(**settings)
    options = {"rig_name": rig.name, "control_names": list(rig.used_controls)}
    options.update(model.rig_fit_options(rig=rig, placement=placement))
    return InverseMapping(model, placement).fit(X, Y, **options)


def joint_error(rig, mapping, X) -> float:
    posed = rig.evaluate(rig.expand_used(mapping.predict(X)))
    return float(((posed.reshape(len(X), -1) - X[:, : 3 * rig.n_joints]) ** 2).mean())


def test_training_on_a_tiny_set_drives_its_joint_error_toward_zero(tiny):
    rig, _, X, _ = tiny
    untrained = joint_error(rig, fitted(tiny, epochs=0), X)
    trained_model = fitted(tiny)
    trained = joint_error(rig, trained_model, X)
    history = [epoch["joint"] for epoch in trained_model.regressor.history_["joint_space"]]
    assert untrained > 10.0  # cm²: the start (the targets' mean) is far off
    assert trained < 0.01 * untrained
    assert history[-1] < 0.01 * history[0]


def test_outputs_never_leave_the_soft_ranges(tiny, tmp_path):
    rig, placement, X, _ = tiny
    mapping = fitted(tiny, epochs=2, n_gaussian=50, n_wide=50, pretrain_epochs=3)
    model = mapping.regressor
    inputs = placement.inputs(X)
    wild = inputs.mean(0) + 1e4 * np.random.default_rng(2).normal(size=(500, inputs.shape[1]))
    predicted = model.predict(np.concatenate([inputs, wild]))
    used = rig.controls.used_indices
    bounded = [i for i in range(len(used)) if i not in {c.index for c in placement.channels}]
    lower, upper = rig.controls.lower[used][bounded], rig.controls.upper[used][bounded]
    assert (predicted[:, bounded] >= lower).all() and (predicted[:, bounded] <= upper).all()
    assert np.abs(predicted[len(X) :, bounded] - upper).min() < 1e-3 * (upper - lower).max()
    # and the saved model predicts the same
    mapping.save(tmp_path)
    loaded = load_regressor(tmp_path, rig=rig)
    np.testing.assert_allclose(loaded.predict(X), mapping.predict(X), atol=1e-5)


def test_local_draws_move_each_control_of_a_pool_row_by_its_own_noise():
    rng = np.random.default_rng(0)
    pool = np.array([[0.0, 10.0, -5.0], [1.0, 20.0, 5.0]])
    std = np.array([0.1, 2.0, 0.0])  # the last control never moves in the corpus
    draws = local_draws(pool, std, 3.0, 40_000, rng)
    assert set(np.unique(draws[:, 2])) == {-5.0, 5.0}  # no noise at std 0: it names the row
    nearest = (draws[:, 2] > 0).astype(int)
    noise = draws - pool[nearest]
    np.testing.assert_allclose(noise.std(axis=0), 3.0 * std, rtol=0.02)
    assert (np.abs(noise.mean(axis=0)) <= 4 * 3.0 * std / np.sqrt(len(draws))).all()  # 4 SE
    assert abs(np.corrcoef(noise[:, 0], noise[:, 1])[0, 1]) < 0.02  # independent controls
    assert 0.48 < (nearest == 0).mean() < 0.52  # rows drawn evenly


def test_local_draws_join_the_fit_inside_the_soft_ranges(tiny):
    rig, placement, _, Y = tiny
    rng = np.random.default_rng(1)
    controls = draw_training_controls(
        rig, placement, Y, 20, 1.0, 10, rng, n_local=30, local_scale=50.0
    )
    X_drawn, Y_drawn = pose_training_draws(rig, placement, controls)
    assert X_drawn.shape == (60, placement.input_width) and len(Y_drawn) == 60
    used = rig.controls.used_indices
    bounded = [i for i in range(len(used)) if i not in {c.index for c in placement.channels}]
    lower, upper = rig.controls.lower[used][bounded], rig.controls.upper[used][bounded]
    local = Y_drawn[20:50, bounded]  # 50 stds out: clamped onto the ranges' ends
    assert (local >= lower).all() and (local <= upper).all()
    assert np.isclose(local, lower).any() and np.isclose(local, upper).any()
    model = JointSpaceNetworkRegressor(n_local=-1)
    with pytest.raises(ValueError, match="n_local must be >= 0"):
        model._check_params()


def test_learned_inputs_are_the_rows_and_the_fits_own_draws_checked_by_summary(tiny, tmp_path):
    rig, placement, X, Y = tiny
    mapping = fitted(tiny, epochs=1, n_gaussian=20, n_local=15, n_wide=10, pretrain_epochs=1)
    inputs, targets = placement.inputs(X), placement.targets(Y, X)
    controls = draw_training_controls(
        rig, placement, targets, 20, 1.0, 10, np.random.default_rng(0), n_local=15, local_scale=2.0
    )
    drawn, _ = pose_training_draws(rig, placement, controls)
    learned = mapping.regressor.learned_inputs(inputs, targets, rig=rig, placement=placement)
    np.testing.assert_array_equal(learned, np.concatenate([inputs, drawn]))
    mapping.save(tmp_path)
    loaded = load_regressor(tmp_path, rig=rig).regressor  # the summary travels in the file
    np.testing.assert_array_equal(
        loaded.learned_inputs(inputs, targets, rig=rig, placement=placement), learned
    )
    with pytest.raises(ModelFileError, match="differ from the fit's"):
        loaded.learned_inputs(inputs[1:], targets[1:], rig=rig, placement=placement)
    loaded.draws_summary_ = None
    with pytest.raises(ModelFileError, match="no summary of its draws"):
        loaded.learned_inputs(inputs, targets, rig=rig, placement=placement)
    # a hand-edited summary is refused when the file loads, naming the file
    meta_path = tmp_path / "nn_joint_space.json"
    meta = json.loads(meta_path.read_text())
    meta["draws_summary"]["mean"] = "0; touch X"
    meta_path.write_text(json.dumps(meta))
    with pytest.raises(
        ModelFileError, match=r"not a valid nn_joint_space model \(draws_summary\['mean'\] must be"
    ):
        load_regressor(tmp_path, rig=rig)


def test_draws_posed_a_few_ulps_away_are_the_same_draws_and_other_draws_are_not():
    # another CPU code path (issue #36: ATEN_CPU_CAPABILITY=default) poses the same drawn
    # controls a few ulps away; a model pulled from the remote must still evaluate there
    draws = np.random.default_rng(0).normal(50.0, 20.0, (500, 12))
    summary = draws_summary(draws)
    assert same_draws(summary, draws * (1 + 4e-16) + 1e-14)
    assert not same_draws(summary, draws[1:])  # one row fewer
    assert not same_draws(summary, draws + 1e-4)  # other poses
    assert not same_draws(summary, np.random.default_rng(1).normal(50.0, 20.0, (500, 12)))


def test_novelty_averages_the_nearest_learned_frames():
    training = np.zeros((7, 6))
    training[:, 0] = np.arange(7.0)  # one joint moved 0, 1, ..., 6 cm along x (2 joints)
    query = np.zeros((1, 6))
    query[0, 0] = -1.0
    np.testing.assert_allclose(
        Novelty.from_training(training, 2, neighbours=3).distances(query), [2.0 / np.sqrt(2)]
    )
    np.testing.assert_allclose(Novelty.from_training(training, 2, 1).distances(query), [1 / 2**0.5])
    assert Novelty.from_training(training[:2], 2).distances(query)[0] == pytest.approx(1.5 / 2**0.5)
    with pytest.raises(MetricInputError, match="neighbours must be an integer >= 1"):
        Novelty.from_training(training, 2, neighbours=0)


def test_the_joint_space_networks_novelty_is_to_its_draws_too(tiny):
    rig, placement, X, Y = tiny
    mapping = fitted(tiny, epochs=1, n_gaussian=200, n_wide=200, pretrain_epochs=1)
    kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
    test_set = TestSet("tiny", [], list(rig.used_controls), kinds, np.ones(len(kinds)), None, X, Y)
    far, _ = corpus(rig, 30, seed=5, spread=0.9)
    novelty = _novelty_of(mapping, test_set, rig)(far)
    learned = mapping.regressor.learned_inputs(
        placement.inputs(X), placement.targets(Y, X), rig=rig, placement=placement
    )
    expected = Novelty.from_training(learned, rig.n_joints).distances(placement.inputs(far))
    np.testing.assert_array_equal(novelty, expected)
    to_corpus = Novelty.from_training(placement.inputs(X), rig.n_joints)
    corpus_only = to_corpus.distances(placement.inputs(far))
    assert (novelty <= corpus_only).all() and novelty.mean() < 0.8 * corpus_only.mean()


def test_a_rig_without_gradients_gets_a_clear_error(tiny):
    placement = tiny[1]

    class BlackBox:
        name, differentiable = "rigify_wolf", False

    with pytest.raises(NotDifferentiableRigError, match="forward surrogate"):
        PlacedRigForward(BlackBox(), placement)


def test_tuning_on_the_target_lowers_its_joint_error_and_keeps_the_model(tiny):
    from rigmap.regression.target_tuning import TuningSettings, tune_on_targets

    rig = tiny[0]
    mapping = fitted(tiny, epochs=20)
    targets, _ = corpus(rig, 30, seed=5, spread=0.5)  # poses it was not trained on
    before = joint_error(rig, mapping, targets)
    prediction = mapping.predict(targets)
    tuned, report = tune_on_targets(
        mapping, rig, targets, TuningSettings(steps=150, learning_rate=3e-3, control_weight=0.001)
    )
    after = joint_error(rig, tuned, targets)
    assert after < 0.2 * before
    assert report["last"]["joint"] < 0.2 * report["first"]["joint"]
    np.testing.assert_array_equal(mapping.predict(targets), prediction)  # the original is kept


def test_the_joint_space_schedule_warms_up_to_its_peak_and_decays_to_its_final_fraction():
    model = JointSpaceNetworkRegressor(
        learning_rate=1e-3, joint_learning_rate=4e-3, warmup=0.2, final_fraction=0.01
    )
    model.network_ = torch.nn.Linear(2, 2)
    optimizer, schedule = model._joint_schedule(100)
    rates = []
    for _ in range(100):
        rates.append(optimizer.param_groups[0]["lr"])
        optimizer.step()
        schedule.step()
    rates.append(optimizer.param_groups[0]["lr"])
    assert rates[0] == pytest.approx(4e-4)  # a tenth of the peak
    assert max(rates) == pytest.approx(4e-3) and int(np.argmax(rates)) == 20
    assert all(a <= b for a, b in itertools.pairwise(rates[:21]))
    assert all(a >= b for a, b in itertools.pairwise(rates[20:]))
    assert rates[-1] == pytest.approx(4e-5)  # final_fraction of the peak
    # without its own rate the joint-space phase runs at learning_rate
    assert JointSpaceNetworkRegressor(learning_rate=2e-3).joint_rate == 2e-3
    for bad in ({"warmup": 1.5}, {"final_fraction": -0.1}, {"joint_learning_rate": 0.0}):
        with pytest.raises(ValueError, match="must be"):
            JointSpaceNetworkRegressor(**bad)._check_params()


def test_the_compiled_forward_equals_the_eager_one_with_its_gradient(tiny):
    """``compiled_rows`` pads a short batch and chunks a long one: same poses, same gradients."""
    rig, placement, X, Y = tiny
    eager, compiled = (
        PlacedRigForward(rig, placement),
        PlacedRigForward(rig, placement, compiled_rows=8),
    )
    for n in (5, 11):
        targets = torch.from_numpy(placement.targets(Y[:n], X[:n]))
        results = []
        for forward in (eager, compiled):
            t = targets.clone().requires_grad_(True)
            posed = forward(t)
            loss = posed.joints.square().sum() + posed.cog.square().sum()
            results.append((posed, torch.autograd.grad(loss, t)[0]))
        (want, want_grad), (got, got_grad) = results
        torch.testing.assert_close(got.joints, want.joints, rtol=0, atol=1e-10)
        torch.testing.assert_close(got.cog, want.cog, rtol=0, atol=1e-10)
        assert want_grad.abs().max() > 1e-3
        torch.testing.assert_close(got_grad, want_grad, rtol=0, atol=1e-10)


def test_a_long_enough_joint_space_phase_trains_through_the_compiled_rig(tiny, monkeypatch):
    """Past ``compiled_rig_min_steps`` the fit poses through ``compiled_pose`` and learns
    what the eager fit learns (float32: equal up to rounding carried through the steps)."""
    rig = tiny[0]
    sizes = []
    original = type(rig).compiled_pose
    monkeypatch.setattr(
        type(rig),
        "compiled_pose",
        lambda self, Y, size: (sizes.append(size), original(self, Y, size))[1],
    )
    eager = fitted(tiny, epochs=20, compiled_rig_min_steps=21)  # 20 steps: below the bar
    assert sizes == []
    compiled = fitted(tiny, epochs=20, compiled_rig_min_steps=20)
    assert set(sizes) == {40} and len(sizes) == 20
    inputs = tiny[2]
    np.testing.assert_allclose(compiled.predict(inputs), eager.predict(inputs), atol=1e-3)
    assert compiled.regressor.history_["joint_space"][-1]["joint"] == pytest.approx(
        eager.regressor.history_["joint_space"][-1]["joint"], rel=1e-3
    )


def test_compiled_rig_min_steps_must_be_a_step_count_or_null():
    for bad in (0, -3, True, "many", 1000.5):
        with pytest.raises(ValueError, match="compiled_rig_min_steps must be a step count"):
            JointSpaceNetworkRegressor(compiled_rig_min_steps=bad)._check_params()
    JointSpaceNetworkRegressor(compiled_rig_min_steps=None)._check_params()


def test_a_rig_without_a_compiled_pass_is_refused_by_name_and_run_eagerly_by_the_fit():
    """The face rig (differentiable, no compiled pass): asked directly, a one-line error; the
    fit's threshold leaves it eager."""
    face = load("face")
    used = len(face.controls.used_indices)
    placement = find_placement(face, np.zeros((2, used)))
    with pytest.raises(NotDifferentiableRigError, match="'face' has no compiled pass"):
        PlacedRigForward(face, placement, compiled_rows=8)
    assert not JointSpaceNetworkRegressor(compiled_rig_min_steps=1)._compiles(face, 100)
    assert JointSpaceNetworkRegressor(compiled_rig_min_steps=1)._compiles(tiny_rig(), 100)


def test_a_warm_up_call_tunes_a_few_steps_and_leaves_the_timed_call_as_it_was(tiny):
    """The evaluation's untimed warm-up (rigmap.evaluation.retargeter.Retargeter.warm_up):
    a tuned method's warm-up call takes WARMUP_STEPS steps, not its 160, and the timed call
    after it returns what it returns without one (each call tunes a fresh copy, seeded)."""
    from rigmap.evaluation.timing import run_timed
    from rigmap.regression.target_tuning import WARMUP_STEPS, TunedOnTarget, TuningSettings

    rig = tiny[0]
    mapping = fitted(tiny, epochs=20)
    targets, _ = corpus(rig, 12, seed=5, spread=0.5)
    settings = TuningSettings(steps=40, learning_rate=3e-3)
    cold = TunedOnTarget(mapping, rig, settings).predict(targets)
    tuned = TunedOnTarget(mapping, rig, settings)

    def warm_up(rows):
        with tuned.warming_up():
            return tuned.predict(rows)

    result, timing = run_timed(tuned.predict, targets, warmup_frames=1, warmup=warm_up)
    warm, timed = tuned.reports
    assert warm["settings"]["steps"] == WARMUP_STEPS and warm["rows"] == 1
    assert timed["settings"]["steps"] == 40 and timed["rows"] == 12
    assert tuned.settings == settings  # restored after the warm-up
    np.testing.assert_array_equal(result, cold)
    assert timing.warmup_frames == 1 and timing.warmup_seconds > 0
