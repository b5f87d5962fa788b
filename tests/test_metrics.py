"""Joint and ground-truth errors (§6.1), method results and their files, timing, rig counting."""

from __future__ import annotations

import json
import time

import numpy as np
import pandas as pd
import pytest

from rig_poses import random_used_controls
from rigmap.evaluation import (
    ClipResult,
    CountingRig,
    MethodResult,
    MetricInputError,
    Stopwatch,
    control_std,
    ground_truth_error,
    joint_error,
    run_timed,
    write_per_frame_csv,
)
from rigmap.refine import ComputedJacobian
from rigmap.rigs.base import RigInputError

# --------------------------------------------------------------------------- joint error


def test_joint_error_by_hand():
    target = np.zeros((2, 2, 3))
    pred = target.copy()
    pred[0, 1] = [3.0, 0.0, 0.0]  # one joint 3 cm off: 9 / 6 coordinates
    pred[1] = [1.0, 2.0, 2.0]  # both joints 3 cm off: 18 / 6
    errors = joint_error(pred, target)
    np.testing.assert_allclose(errors.per_frame, [1.5, 3.0])
    assert errors.mean == pytest.approx(2.25)
    # flat (N, 3J) and (N, J, 3) layouts mix freely
    np.testing.assert_allclose(joint_error(pred.reshape(2, 6), target).per_frame, [1.5, 3.0])


def test_joint_error_on_the_biped_is_a_third_of_mean_squared_joint_distance(biped):
    Y = random_used_controls(biped, 6, seed=11)
    Y_off = random_used_controls(biped, 6, seed=12)
    X, X_off = biped.evaluate(Y), biped.evaluate(Y_off)
    errors = joint_error(X_off, X)
    squared_distance = (np.linalg.norm(X_off - X, axis=2) ** 2).mean(axis=1)
    np.testing.assert_allclose(errors.per_frame, squared_distance / 3, rtol=1e-12)
    assert errors.mean > 0.1  # different poses really differ (cm²)
    assert joint_error(X, X).mean == 0.0


def test_joint_error_refuses_bad_input():
    good = np.zeros((3, 4, 3))
    with pytest.raises(MetricInputError, match=r"X_pred has 3 frames x 12 .* X_target has 2 x 12"):
        joint_error(good, good[:2])
    with pytest.raises(
        MetricInputError, match=r"X_target: .*\(N, J, 3\) or \(N, 3J\), got \(3, 4\)"
    ):
        joint_error(good, np.zeros((3, 4)))
    bad = good.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(MetricInputError, match=r"X_pred: contains NaN .*\(1, 2, 0\)"):
        joint_error(bad, good)


# --------------------------------------------------------------------------- ground truth


def test_ground_truth_error_by_hand_skips_constant_controls():
    kinds = ["rotate", "translate", "scalar"]
    names = ["arm.rx", "root.tx", "hand.curl"]
    std = np.array([2.0, 0.5, 0.0])  # the curl never moved in training
    true = np.zeros((2, 3))
    pred = np.array([[2.0, 0.5, 0.25], [4.0, 0.0, 0.0]])
    result = ground_truth_error(pred, true, std, kinds, names=names)
    # frame 0: ((2/2)^2 + (0.5/0.5)^2) / 2 = 1; frame 1: ((4/2)^2 + 0) / 2 = 2
    np.testing.assert_allclose(result.per_frame, [1.0, 2.0])
    assert result.mean == pytest.approx(1.5)
    assert result.per_kind == pytest.approx({"rotate": 2.5, "translate": 0.5})
    assert result.scored_controls == 2
    assert result.skipped == ("hand.curl",)
    assert result.skipped_max_abs_difference == 0.25


def test_ground_truth_error_does_not_depend_on_units():
    rng = np.random.default_rng(3)
    train = rng.normal(size=(50, 4)) * [0.3, 12.0, 1.0, 40.0]
    true, pred = train[:10], train[:10] + rng.normal(size=(10, 4))
    kinds = ["rotate", "translate", "scalar", "translate"]
    in_cm = ground_truth_error(pred, true, control_std(train), kinds)
    to_m = np.array([1.0, 0.01, 1.0, 0.01])  # translations in metres instead of cm
    in_m = ground_truth_error(pred * to_m, true * to_m, control_std(train * to_m), kinds)
    np.testing.assert_allclose(in_m.per_frame, in_cm.per_frame, rtol=1e-12)
    assert in_cm.skipped == ()


def test_constant_threshold_and_refusals():
    true = np.zeros((1, 2))
    pred = np.ones((1, 2))
    tiny = ground_truth_error(pred, true, [1e-12, 1.0], ["scalar", "scalar"])
    assert tiny.skipped == ("control[0]",) and tiny.mean == 1.0
    small = ground_truth_error(pred, true, [1e-6, 1.0], ["scalar", "scalar"])
    assert small.skipped == () and small.mean == pytest.approx((1e12 + 1) / 2)
    with pytest.raises(MetricInputError, match="all 2 controls have a training std"):
        ground_truth_error(pred, true, [0.0, 0.0], ["scalar", "scalar"])
    with pytest.raises(MetricInputError, match=r"unknown control kinds \['angle'\]"):
        ground_truth_error(pred, true, [1.0, 1.0], ["angle", "scalar"])
    with pytest.raises(MetricInputError, match=r"expected 2 control kinds, got 1"):
        ground_truth_error(pred, true, [1.0, 1.0], ["scalar"])
    with pytest.raises(MetricInputError, match=r"train_std of shape \(2,\)"):
        ground_truth_error(pred, true, [1.0, -1.0], ["scalar", "scalar"])
    with pytest.raises(MetricInputError, match=r"same shape .* \(1, 2\) and \(1, 3\)"):
        ground_truth_error(pred, np.zeros((1, 3)), [1.0, 1.0], ["scalar", "scalar"])


def test_control_std_is_the_population_std():
    Y = np.array([[0.0, 1.0], [2.0, 1.0], [4.0, 1.0]])
    np.testing.assert_allclose(control_std(Y), [np.sqrt(8 / 3), 0.0])
    with pytest.raises(MetricInputError, match=r"N >= 2"):
        control_std(Y[:1])


# --------------------------------------------------------------------------- results


def _result() -> MethodResult:
    clips = [
        ClipResult("jump & play", [1.0, 3.0], [0.5, 0.5], total_time_s=0.5, rig_evaluations=4,
                   rig_calls=2, frame_numbers=np.array([10, 11])),
        ClipResult("tai chi", [8.0], [2.0], total_time_s=1.0, rig_evaluations=1, rig_calls=1),
    ]  # fmt: skip
    return MethodResult("biped", "gpr", "none", clips, warmup_frames=1, skipped_controls=("x",))


def test_method_result_averages_over_frames_not_clips():
    result = _result()
    assert result.frames == 3
    assert result.joint_error == pytest.approx(4.0)  # (1 + 3 + 8) / 3, not (2 + 8) / 2
    assert result.ground_truth_error == pytest.approx(1.0)
    assert result.total_time_s == 1.5
    assert result.fps == pytest.approx(2.0)
    assert result.rig_evaluations == 5 and result.rig_calls == 3
    assert result.clips[0].fps == pytest.approx(4.0)


def test_metrics_json_and_per_frame_csv(tmp_path):
    result = _result()
    path = result.write_json(tmp_path / "metrics" / "biped" / "gpr-none.json")
    saved = json.loads(path.read_text())
    assert saved["average"] == pytest.approx(result.average())
    assert saved["clips"]["jump & play"]["joint_error"] == 2.0
    assert saved["clips"]["tai chi"]["fps"] == 1.0
    assert saved["timing"]["warmup_frames"] == 1 and saved["timing"]["warmup_excluded"]
    assert saved["units"]["joint_error"].startswith("cm^2")
    assert saved["ground_truth_error_skipped_controls"]["names"] == ["x"]
    csv = write_per_frame_csv(result, tmp_path / "per_frame.csv")
    table = pd.read_csv(csv)
    assert list(table.columns) == ["clip", "frame", "joint_error", "ground_truth_error"]
    assert table["frame"].tolist() == [10, 11, 0]
    assert table["joint_error"].tolist() == [1.0, 3.0, 8.0]
    assert sorted(p.name for p in tmp_path.rglob("*")) == sorted(
        ["metrics", "biped", "gpr-none.json", "per_frame.csv"]
    )  # no temp files left behind


def test_results_refuse_bad_input():
    with pytest.raises(MetricInputError, match=r"clip 'a': expected 2 ground-truth errors"):
        ClipResult("a", [1.0, 2.0], [1.0], total_time_s=1.0)
    with pytest.raises(MetricInputError, match=r"clip 'a': total_time_s must be a positive"):
        ClipResult("a", [1.0], [1.0], total_time_s=0.0)
    with pytest.raises(MetricInputError, match=r"rig_evaluations must be a count"):
        ClipResult("a", [1.0], [1.0], total_time_s=1.0, rig_evaluations=-1)
    with pytest.raises(MetricInputError, match=r"contains NaN"):
        ClipResult("a", [np.nan], [1.0], total_time_s=1.0)
    clip = ClipResult("a", [1.0], [1.0], total_time_s=1.0)
    with pytest.raises(MetricInputError, match=r"clips repeated: \['a'\]"):
        MethodResult("biped", "gpr", "none", [clip, clip])
    with pytest.raises(MetricInputError, match="no clip results"):
        MethodResult("biped", "gpr", "none", [])


# --------------------------------------------------------------------------- timing


def test_stopwatch_accumulates_laps():
    watch = Stopwatch()
    with watch:
        time.sleep(0.01)
    first = watch.elapsed
    with watch:
        time.sleep(0.01)
    assert watch.laps == 2 and first >= 0.01 and watch.elapsed >= first + 0.01
    with pytest.raises(RuntimeError, match="not running"):
        watch.stop()


def test_run_timed_warms_up_on_the_first_frames_then_times_all():
    seen = []

    def run(frames):
        seen.append(frames.copy())
        return frames * 2

    frames = np.arange(5.0)
    result, timing = run_timed(run, frames, warmup_frames=2)
    assert [s.tolist() for s in seen] == [[0.0, 1.0], [0.0, 1.0, 2.0, 3.0, 4.0]]
    np.testing.assert_array_equal(result, frames * 2)
    assert timing.frames == 5 and timing.warmup_frames == 2
    assert timing.seconds > 0 and timing.fps == pytest.approx(5 / timing.seconds)
    _, no_warmup = run_timed(run, frames, warmup_frames=0)
    assert no_warmup.warmup_seconds == 0.0 and len(seen) == 3
    with pytest.raises(ValueError, match="warmup_frames must be an integer >= 0"):
        run_timed(run, frames, warmup_frames=-1)
    warmed = []  # a warm-up call of its own (a tuned method's, fewer steps): the timed run's
    result, _ = run_timed(run, frames, warmup_frames=2, warmup=lambda f: warmed.append(f.copy()))
    assert [w.tolist() for w in warmed] == [[0.0, 1.0]] and len(seen) == 4
    np.testing.assert_array_equal(result, frames * 2)


def test_counting_rig_counts_timed_poses_only(biped):
    rig = CountingRig(biped)
    Y = random_used_controls(biped, 7, seed=5)
    X, timing = run_timed(rig.evaluate, Y, warmup_frames=3, rig=rig)
    np.testing.assert_array_equal(X, biped.evaluate(Y))
    assert timing.rig.calls == 1 and timing.rig.poses == 7  # the 3 warm-up poses are not counted
    rig.pose(Y[0])  # one control vector is one pose
    assert rig.count.calls == 2 and rig.count.poses == 8
    # everything else is the wrapped rig's
    assert rig.name == "biped" and rig.n_joints == biped.n_joints and rig.wrapped is biped
    np.testing.assert_array_equal(rig.expand_used(Y[:, biped.controls.used_indices]), Y)
    with pytest.raises(RigInputError, match="expected controls of shape"):
        rig.evaluate(Y[:, :5])
    assert rig.count.calls == 2  # a failed call evaluated nothing
    assert rig.reset().poses == 8 and rig.count.poses == 0


def test_counting_rig_agrees_with_refinement_cost(biped):
    """Finite-difference Jacobians through the wrapper: 2 poses per used control per frame."""
    rig = CountingRig(biped)
    Y = random_used_controls(biped, 2, seed=9)
    _, cost = ComputedJacobian(rig)(Y, biped.evaluate(Y))
    assert rig.count.poses == cost == 2 * 2 * len(biped.controls.used_indices)


def test_counting_rig_needs_the_rig_protocol():
    with pytest.raises(TypeError, match=r"has no callable evaluate, pose"):
        CountingRig(object())
