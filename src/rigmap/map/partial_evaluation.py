"""How well a few joints pose the whole body: partial input on the test clips (§6.3, Figs 5-6).

The paper poses its dog from the four feet (Fig. 6) and from seven effectors (Fig. 5) and
shows the result beside the animator's pose. :func:`evaluate_partial_inputs` measures the
same on a rig's held-out test clips: for each joint subset (and the full joint set beside
it) a :class:`rigmap.map.partial.SubsetMapping` is fitted on the train corpus's poses,
given the test clips' world positions of its joints, and optionally refined on them
(:func:`rigmap.map.clip.solve_controls`: damped least squares with the prior toward the
guess). It reports, in cm RMS over frames and joints, the error on the *given* joints
(what the input asked for) and on the *whole body* (what the animator had), plus the
ground-truth control error of §6.1.

Refinement is the costly part (a finite-difference Jacobian per frame); ``refine_every``
refines every n-th test frame only (the guess is scored on every frame), which keeps the
``map_partial`` stage inside its quick budget. The stride is ours.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from rigmap.error_measures import ground_truth_error
from rigmap.map.clip import MapSettings, solve_controls
from rigmap.map.partial import JointSubset, SubsetMapping
from rigmap.regression.features import inverse_features

FULL_INPUT = "full"  # the name of the row with every rig joint as input


@dataclass(frozen=True)
class PartialInputSettings:
    """Refinement of the partial-input evaluation; every default is ours."""

    refine_iterations: int = 2
    refine_every: int = 4
    prior_weight: float = 1.0
    damping: float | str = "auto"

    def __post_init__(self) -> None:
        if not (isinstance(self.refine_every, int) and self.refine_every >= 1):
            raise ValueError(f"refine_every {self.refine_every!r} must be an integer >= 1")


@dataclass(frozen=True)
class TrainingData:
    """A rig's train corpus as a subset mapping learns from it."""

    X_pose: np.ndarray  # (N, 3J + 12) pose rows around the real COG
    Y_used: np.ndarray  # (N, U)
    std: np.ndarray  # (U,) training std per used control
    median: np.ndarray  # (U,) what held controls (IK/FK switches) keep


def training_data(rig, poses_table, Y_used: np.ndarray) -> TrainingData:
    """From the train split's :class:`rigmap.animation.posing.PoseTable` and controls."""
    X = inverse_features(
        poses_table.positions(),
        poses_table.cog(),
        poses_table.cog_rotation(),
        n_joints=rig.n_joints,
        where=f"{rig.name} train poses",
    )
    Y = np.asarray(Y_used, dtype=np.float64)
    return TrainingData(X, Y, Y.std(axis=0), np.median(Y, axis=0))


def full_subset(rig, like: JointSubset) -> JointSubset:
    """Every rig joint as input, framed by the same origin and left/right joints as ``like``."""
    return JointSubset(
        FULL_INPUT, rig.name, tuple(rig.joint_names), like.origin, like.left, like.right
    )


@dataclass(frozen=True)
class PartialInputRow:
    """One subset's scores over the test clips (cm RMS; ground truth in std², §6.1)."""

    rig: str
    subset: str
    given_joints: int
    stage: str  # "guess" (regression only) or "refined"
    frames: int
    given_error_cm: float
    body_error_cm: float
    ground_truth_error: float
    seconds: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def fit_subset_mappings(
    rig,
    subsets: Mapping[str, JointSubset],
    training: TrainingData,
    make_regressor: Callable[[], object],
) -> dict[str, tuple[SubsetMapping, float]]:
    """Per subset name (the full joint set first), its fitted mapping and the fit's seconds."""
    first = next(iter(subsets.values()))
    fitted = {}
    for subset in [full_subset(rig, first), *subsets.values()]:
        started = time.perf_counter()
        mapping = SubsetMapping.fit(rig, subset, training.X_pose, training.Y_used, make_regressor())
        fitted[subset.name] = (mapping, time.perf_counter() - started)
    return fitted


def evaluate_partial_inputs(
    rig,
    fitted: Mapping[str, tuple[SubsetMapping, float]],
    training: TrainingData,
    test_set,
    settings: PartialInputSettings,
) -> list[PartialInputRow]:
    """Rows per fitted subset for ``test_set`` (:class:`rigmap.evaluation.methods.TestSet`):
    the guess on every frame, then the refinement on every ``settings.refine_every``-th
    frame when it iterates. The guess's seconds include the fit."""
    rows = []
    for mapping, fit_s in fitted.values():
        rows += _score_subset(rig, mapping, training, test_set, settings, fit_s)
    return rows


def _score_subset(rig, mapping, training, test_set, settings, fit_s) -> list[PartialInputRow]:
    world = np.concatenate([c.positions + c.cog[:, None, :] for c in test_set.clips])
    truth = np.concatenate([c.controls for c in test_set.clips])
    given = mapping.subset.columns(rig)
    started = time.perf_counter()
    guess = mapping.predict(world[:, given])
    rows = [
        _row(
            rig,
            mapping.subset,
            "guess",
            guess,
            world,
            truth,
            training,
            test_set,
            fit_s + time.perf_counter() - started,
        )
    ]
    if settings.refine_iterations == 0:
        return rows
    frames = np.arange(0, len(world), settings.refine_every)
    map_settings = MapSettings(
        refine_iterations=settings.refine_iterations,
        damping=settings.damping,
        prior_weight=settings.prior_weight,
    )
    started = time.perf_counter()
    refined = solve_controls(
        rig, mapping, world[frames][:, given], map_settings, training.std, training.median, {}
    )
    rows.append(
        _row(
            rig,
            mapping.subset,
            "refined",
            refined,
            world[frames],
            truth[frames],
            training,
            test_set,
            time.perf_counter() - started,
        )
    )
    return rows


def _row(rig, subset, stage, Y_used, world, truth, training, test_set, seconds):
    pose = rig.pose(rig.expand_used(Y_used))
    reached = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
    distance = np.linalg.norm(reached - world, axis=2)  # (N, J) cm
    given = subset.columns(rig)
    gt = ground_truth_error(
        Y_used, truth, test_set.train_std, test_set.control_kinds, names=test_set.control_names
    )
    return PartialInputRow(
        rig.name,
        subset.name,
        len(given),
        stage,
        len(world),
        float(np.sqrt((distance[:, given] ** 2).mean())),
        float(np.sqrt((distance**2).mean())),
        gt.mean,
        float(seconds),
    )
