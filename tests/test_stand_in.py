"""The learned forward stand-in of a rig torch cannot differentiate (issue #39)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rigmap.regression.errors import ModelMismatchError
from rigmap.regression.stand_in import (
    StandInSettings,
    fit_stand_in,
    load_stand_in,
    save_stand_in,
)
from rigmap.rigs.base import Control, ControlTable, Pose, Rig, RigInputError


class ArmRig(Rig):
    """A black-box arm: a slide of the whole arm (a root channel), a shoulder and an elbow
    angle, and an unused control; shoulder, elbow and hand joints around a fixed COG."""

    def __init__(self, name: str = "arm", forearm: float = 25.0):
        self.name = name
        self.forearm = forearm
        self.controls = ControlTable(
            [
                Control("slide", "translate", 0.0, -50.0, 50.0, True, "root"),
                Control("shoulder", "rotate", 0.0, -1.5, 1.5, True, "arm"),
                Control("elbow", "rotate", 0.3, 0.0, 2.5, True, "arm"),
                Control("unused", "scalar", 0.0, -1.0, 1.0, False, "arm"),
            ]
        )
        self.joint_names = ["shoulder", "elbow", "hand"]
        self.parents = np.array([-1, 0, 1])

    def _pose(self, Y) -> Pose:
        Y = np.asarray(Y, dtype=np.float64)
        n = len(Y)
        a, b = Y[:, 1], Y[:, 1] + Y[:, 2]
        shoulder = np.zeros((n, 3))
        elbow = shoulder + 30.0 * np.stack([np.cos(a), np.sin(a), np.zeros(n)], 1)
        hand = elbow + self.forearm * np.stack([np.cos(b), np.sin(b), np.zeros(n)], 1)
        joints = np.stack([shoulder, elbow, hand], 1)
        cog = joints.mean(axis=1)
        cog[:, 0] += Y[:, 0]
        turn = np.stack([np.cos(a), np.sin(a), np.zeros(n)], 1)
        rotation = np.zeros((n, 3, 3))
        rotation[:, :, 0], rotation[:, 2, 2] = turn, 1.0
        rotation[:, 0, 1], rotation[:, 1, 1] = -turn[:, 1], turn[:, 0]
        return Pose(joints - joints.mean(axis=1, keepdims=True), cog, rotation)


ROOT = [0]  # the slide, among the used controls


def draws(rig: Rig, n: int, seed: int = 0) -> np.ndarray:
    used = rig.controls.used_indices
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    controls = np.random.default_rng(seed).uniform(lower, upper, (n, len(used)))
    controls[:, ROOT] = 0.0
    return controls


def fitted(rig: Rig, n: int = 2000, epochs: int = 60, seed: int = 0):
    controls = draws(rig, n, seed)
    pose = rig.pose(rig.expand_used(controls))
    settings = StandInSettings(hidden=128, layers=3, epochs=epochs, batch_size=64)
    return fit_stand_in(rig, controls, pose, ROOT, settings, progress=False)


@pytest.fixture(scope="module")
def arm():
    return ArmRig()


@pytest.fixture(scope="module")
def stand_in(arm):
    return fitted(arm)


def test_training_longer_drives_the_held_out_error_toward_zero(arm, stand_in):
    short = fitted(arm, epochs=2)
    # the arm reaches 55 cm: a long fit is within a few millimetres on unseen poses
    assert stand_in.fit.heldout_rms_cm < 0.3
    assert stand_in.fit.heldout_rms_cm < short.fit.heldout_rms_cm / 5
    assert set(stand_in.fit.heldout_rms_per_joint_cm) == {"shoulder", "elbow", "hand"}
    assert stand_in.fit.heldout_rows == 200 and stand_in.fit.train_rows == 1800
    # the history is the cost per epoch, and it fell
    assert stand_in.fit.history[-1] < stand_in.fit.history[0] / 10


def test_it_poses_like_the_rig_on_poses_it_never_saw(arm, stand_in):
    controls = draws(arm, 50, seed=7)
    real = arm.pose(arm.expand_used(controls))
    guess = stand_in.pose(arm.expand_used(controls))
    assert isinstance(guess.positions, np.ndarray) and guess.positions.dtype == np.float64
    assert np.abs(guess.positions - real.positions).max() < 2.0
    rotation = guess.cog_rotation
    # the rotation is a rotation: orthonormal columns, determinant one
    assert np.allclose(rotation @ rotation.transpose(0, 2, 1), np.eye(3), atol=1e-6)
    assert np.allclose(np.linalg.det(rotation), 1.0, atol=1e-6)


def test_its_gradient_is_its_own_finite_differences(arm, stand_in):
    assert stand_in.differentiable
    at = torch.from_numpy(arm.expand_used(draws(arm, 3, seed=3)))

    def hand(controls):
        return stand_in.pose(controls).positions[:, 2].sum(0)

    exact = torch.autograd.functional.jacobian(hand, at)
    step = 1e-6
    for column in (1, 2, 3):  # the arm's angles and the unused control
        shift = torch.zeros_like(at)
        shift[:, column] = step
        numeric = (hand(at + shift) - hand(at - shift)) / (2 * step)
        assert torch.allclose(exact[:, :, column].sum(1), numeric, rtol=1e-6, atol=1e-8)
    assert float(exact[:, :, 3].abs().max()) == 0.0  # the unused control moves nothing


def test_a_root_channel_away_from_zero_is_refused(arm, stand_in):
    controls = arm.expand_used(draws(arm, 2))
    controls[1, 0] = 3.0
    with pytest.raises(RigInputError, match=r"root channels at zero \(controls \['slide'\]\)"):
        stand_in.pose(controls)


def test_saved_and_loaded_it_poses_the_same_and_refuses_another_rig(arm, stand_in, tmp_path):
    save_stand_in(stand_in, tmp_path / "stand_in")
    loaded = load_stand_in(tmp_path / "stand_in", arm)
    controls = arm.expand_used(draws(arm, 20, seed=5))
    assert np.array_equal(loaded.pose(controls).positions, stand_in.pose(controls).positions)
    assert loaded.fit.heldout_rms_cm == stand_in.fit.heldout_rms_cm
    with pytest.raises(ModelMismatchError, match=r"stand-in of rig 'arm'.*rig 'leg'"):
        load_stand_in(tmp_path / "stand_in", ArmRig(name="leg"))
    # the same names, but the rig poses differently now: its probe poses say so
    with pytest.raises(ModelMismatchError, match="the rig changed; fit the stand-in again"):
        load_stand_in(tmp_path / "stand_in", ArmRig(forearm=26.0))


def test_a_fit_is_repeatable_from_its_seed(arm, stand_in):
    again = fitted(arm)
    assert again.fit.history == stand_in.fit.history
