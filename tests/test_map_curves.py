"""rigmap.map curves, contacts and key reduction, on the biped and a real CMU walk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigmap.animation.keyframes import FCurve
from rigmap.map import JointMap, tracks_from_bvh
from rigmap.map.contacts import detect_contacts, foot_skate, pin_contacts
from rigmap.map.curves import CurveError, largest_jumps, smooth, unwrap_rotations
from rigmap.map.key_reduction import (
    KeyReductionError,
    reduce_curve,
    reduce_within_joint_tolerance,
)

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_02_walk.bvh"  # a plain walk (01 slides)


def smooth_motion(rig, frames=96, controls=6, seed=0):
    """Full control rows: defaults plus slow sinusoids on a few used controls."""
    rng = np.random.default_rng(seed)
    rows = np.tile(rig.controls.defaults, (frames, 1))
    time = np.arange(frames) / 24.0
    for c in rng.choice(rig.controls.used_indices, controls, replace=False):
        rows[:, c] += 0.3 * np.sin(2 * np.pi * rng.uniform(0.3, 1.0) * time + rng.uniform(0, 6))
    return rows


def test_unwrapping_removes_flips_and_keeps_the_pose(biped):
    rows = np.tile(biped.controls.defaults, (40, 1))
    kinds = list(biped.controls.kinds)
    c = next(i for i in biped.controls.used_indices if kinds[i] == "rotate")
    angle = np.linspace(2.8, 3.6, 40)
    rows[:, c] = (angle + np.pi) % (2 * np.pi) - np.pi  # wrapped into [-π, π): one 2π flip
    assert np.abs(np.diff(rows[:, c])).max() > 6.0
    unwrapped = unwrap_rotations(rows, kinds)
    np.testing.assert_allclose(unwrapped[:, c], angle, atol=1e-12)
    assert largest_jumps(unwrapped[:, [c]], np.array([1.0]))[0] < 0.03
    np.testing.assert_allclose(biped.evaluate(unwrapped), biped.evaluate(rows), atol=1e-9)
    with pytest.raises(CurveError, match="expected"):
        unwrap_rotations(rows[:, :5], kinds)


def test_smoothing_keeps_constants_and_calms_noise():
    rng = np.random.default_rng(1)
    noisy = np.column_stack(
        [np.full(200, 2.0), np.sin(np.arange(200) / 20) + rng.normal(0, 0.1, 200)]
    )
    smoothed = smooth(noisy, 2.0)
    np.testing.assert_allclose(smoothed[:, 0], 2.0, atol=1e-12)
    assert np.abs(np.diff(smoothed[:, 1], 2)).mean() < 0.2 * np.abs(np.diff(noisy[:, 1], 2)).mean()
    np.testing.assert_array_equal(smooth(noisy, 0), noisy)
    with pytest.raises(CurveError, match="sigma"):
        smooth(noisy, -1)


def test_contacts_on_a_real_walk_and_pinning_removes_skate(biped):
    mapped = JointMap.from_yaml(ROOT / "conf/retarget/cmu_biped.yaml").apply(
        biped, tracks_from_bvh(WALK)
    )
    feet = ("foot_l", "foot_r")
    contacts = detect_contacts(mapped.positions, feet, mapped.joint_names, mapped.fps)
    share = contacts.planted.mean(axis=0)
    assert ((share > 0.3) & (share < 0.8)).all(), share  # a walk: each foot down part-time
    assert all(5 <= len(contacts.intervals(k)) <= 20 for k in (0, 1))  # ~10 s of steps
    before = foot_skate(mapped.positions, contacts, mapped.joint_names)
    pinned = pin_contacts(mapped.positions, contacts, mapped.joint_names)
    assert before > 0
    assert foot_skate(pinned, contacts, mapped.joint_names) == 0.0
    unplanted = ~contacts.planted[:, 0]
    j = mapped.joint_names.index("foot_l")
    np.testing.assert_array_equal(pinned[unplanted, j], mapped.positions[unplanted, j])


def test_planted_interval_of_a_synthetic_step():
    frames = np.arange(30)
    foot = np.zeros((30, 1, 3))
    foot[:, 0, 2] = np.where(frames < 10, frames * 5.0, 45.0 + 0.01 * (frames - 10))
    foot[:, 0, 1] = np.where(frames < 10, 5.0, 0.0)  # lifted, then down and nearly still
    contacts = detect_contacts(foot, ["toe"], ["toe"], 30.0)
    assert contacts.intervals(0) == [(10, 29)]
    assert foot_skate(foot, contacts, ["toe"]) == pytest.approx(0.01, abs=1e-12)


def test_reduced_curve_stays_within_tolerance_with_few_keys():
    frames = np.arange(240)
    values = np.sin(frames / 30.0) + 0.3 * np.sin(frames / 7.0)
    curve = reduce_curve(values, 1e-3)
    assert np.abs(curve.evaluate(frames.astype(float)) - values).max() <= 1e-3
    assert len(curve) < 60
    keyed = FCurve.from_pairs([(0, 0.0), (40, 1.0), (90, -0.5), (160, 0.2), (239, 0.0)])
    replay = reduce_curve(keyed.evaluate(frames.astype(float)), 1e-3)
    assert len(replay) <= 20  # a 5-key curve comes back sparse (14 keys at 1e-3)
    assert len(reduce_curve(np.full(50, 3.0), 1e-9)) == 2
    with pytest.raises(KeyReductionError, match="not all finite"):
        reduce_curve(np.array([0.0, np.nan]), 0.1)


def test_joint_tolerance_holds_on_the_biped(biped):
    rows = smooth_motion(biped)
    std = np.full(len(biped.controls.used_indices), 0.2)
    reduced = reduce_within_joint_tolerance(biped, rows, std, tolerance_cm=0.5)
    assert reduced.max_joint_error_cm <= 0.5
    assert reduced.key_count < 0.2 * reduced.frames * len(reduced.curves)
    replay = rows.copy()
    replay[:, biped.controls.used_indices] = reduced.values()
    pose = biped.pose(replay)
    target = biped.pose(rows)
    world = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None]
    want = np.asarray(target.positions) + np.asarray(target.cog)[:, None]
    assert np.linalg.norm(world - want, axis=2).max() <= 0.5


def test_key_reduction_keeps_every_joint_and_a_planted_foot_within_its_tolerance(biped):
    from rigmap.map.key_reduction import JointLimit

    rows = smooth_motion(biped, controls=10, seed=3)
    time = np.arange(len(rows)) / 24.0
    for name in ("leg_l_ik.tx", "leg_l_ik.tz", "cog.ty"):
        rows[:, biped.control_names.index(name)] += 4.0 * np.sin(2 * np.pi * 0.7 * time)
    std = np.full(len(biped.controls.used_indices), 0.2)
    planted = np.zeros(len(rows), dtype=bool)
    planted[20:50] = True
    foot = biped.joint_names.index("foot_l")

    def replay_error(reduced):
        replay = rows.copy()
        replay[:, biped.controls.used_indices] = reduced.values()
        moved = biped.pose(replay)
        target = biped.pose(rows)
        world = np.asarray(moved.positions) + np.asarray(moved.cog)[:, None]
        want = np.asarray(target.positions) + np.asarray(target.cog)[:, None]
        return np.linalg.norm(world - want, axis=2)

    loose = reduce_within_joint_tolerance(biped, rows, std, tolerance_cm=0.5)
    assert replay_error(loose)[planted, foot].max() > 0.02  # the limit below has work to do
    limits = [JointLimit("foot_l", planted, 0.02)]
    held = reduce_within_joint_tolerance(biped, rows, std, tolerance_cm=0.5, limits=limits)
    error = replay_error(held)
    assert error.max() <= 0.5 and held.max_joint_error_cm == pytest.approx(error.max())
    assert error[planted, foot].max() <= 0.02
    assert held.key_count < 0.2 * held.frames * len(held.curves)
    with pytest.raises(KeyReductionError, match="no such joint"):
        reduce_within_joint_tolerance(biped, rows, std, 0.5, limits=[JointLimit("x", planted, 1)])
    with pytest.raises(KeyReductionError, match="frame flags"):
        short = [JointLimit("foot_l", planted[:5], 0.1)]
        reduce_within_joint_tolerance(biped, rows, std, 0.5, limits=short)


def test_ground_penetration_slip_and_flips_of_a_synthetic_step():
    from rigmap.map.contacts import contact_floors, contact_slip, ground_penetration
    from rigmap.map.curves import count_flips

    frames = np.arange(30)
    foot = np.zeros((30, 1, 3))
    foot[:, 0, 2] = np.where(frames < 10, frames * 5.0, 45.0 + 0.01 * (frames - 10))
    foot[:, 0, 1] = np.where(frames < 10, 5.0, 0.0)
    contacts = detect_contacts(foot, ["toe"], ["toe"], 30.0)
    floors = contact_floors(foot, contacts, ["toe"])
    assert floors.tolist() == [0.0]  # its median height while planted
    assert ground_penetration(foot, contacts, ["toe"], floors) == 0.0
    sunk = foot.copy()
    sunk[15, 0, 1] = -1.5
    assert ground_penetration(sunk, contacts, ["toe"], floors) == pytest.approx(1.5)
    pinned = pin_contacts(foot, contacts, ["toe"])
    assert contact_slip(pinned, pinned, contacts, ["toe"]) == 0.0
    assert contact_slip(foot, pinned, contacts, ["toe"]) == pytest.approx(0.095, abs=1e-9)
    angles = np.linspace(3.0, 3.3, 10)
    wrapped = (angles + np.pi) % (2 * np.pi) - np.pi
    assert count_flips(wrapped[:, None], ["rotate"]) == 1
    assert count_flips(angles[:, None], ["rotate"]) == 0
    assert count_flips(wrapped[:, None] * 100, ["translate"]) == 0


def test_the_reducers_hermite_values_are_its_bezier_curves():
    from rigmap.map.key_reduction import _hermite_curve, data_slopes, hermite_values

    rng = np.random.default_rng(4)
    values = np.cumsum(rng.normal(size=60))
    slopes = data_slopes(values)
    for keys in ([0, 59], [0, 7, 8, 30, 59], list(range(60))):
        curve = _hermite_curve(values, slopes, keys, "c")
        np.testing.assert_allclose(
            hermite_values(values, slopes, keys), curve.evaluate(np.arange(60.0)), atol=1e-9
        )
    np.testing.assert_allclose(hermite_values(values, slopes, keys)[keys], values[keys])
