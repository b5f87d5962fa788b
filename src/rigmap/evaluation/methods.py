"""The methods of Table 1 and the runner that scores them on a rig's test clips (paper §6.1).

A *method* is an initial guess (the rig's retarget script, or an inverse
mapping learned by regression) optionally followed by damped-least-squares
refinement (Eq. 13) with the rig's own Jacobian (finite differences, or
autodiff on a built-in rig) or a Jacobian learned by GPR (§4.4):

=======================  ==========  =================================
method                   guess       refinement
=======================  ==========  =================================
script                   script      none
gpr                      gpr         none
gpr_learned_jacobian     gpr         learned Jacobian
gpr_computed_jacobian    gpr         finite-difference Jacobian
nn                       nn          none
nn_computed_jacobian     nn          finite-difference Jacobian
nn_learned_jacobian      nn          learned Jacobian (extra row)
nn_autodiff_jacobian     nn          autodiff Jacobian (extra row)
=======================  ==========  =================================

The stages build these rows from the ``method`` config group (``conf/method/<name>.yaml``,
see :mod:`rigmap.evaluation.method_config`); ``METHODS`` is the same table in code, for
callers without a config (a test checks the two agree).

``run_method`` retargets every test clip, one clip per timed pass: the clock
covers the whole method from the clip's poses to its controls — features,
prediction, every rig evaluation refinement makes — after an untimed warm-up
on the clip's first frames (one-off costs: thread pools, caches, torch
kernel selection). The rig evaluations that *score* the result (joint error)
are measurement, not method, and are neither timed nor counted. Controls the
method does not predict (the rig's unused ones) stay at their defaults.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rigmap.errors import RigmapError
from rigmap.evaluation.metrics import (
    ClipResult,
    MethodResult,
    control_std,
    ground_truth_error,
    joint_error,
)
from rigmap.evaluation.novelty import Novelty
from rigmap.evaluation.timing import CountingRig, run_timed
from rigmap.store import Layout

GUESSES = ("script", "regressor")
REFINEMENTS = ("none", "computed_jacobian", "learned_jacobian")
CONTROL_SCALES = ("training_std", "none")  # the metric refinement damps its steps in
JACOBIANS = ("finite_difference", "autodiff")

#: what the clock covers, written into every metrics JSON
TIMING_SCOPE = (
    "per clip, from its target poses to its controls: input features, the script or "
    "regressor, and refinement with every rig evaluation it makes; the rig evaluations "
    "that score the result (joint error) are not timed or counted"
)


class EvaluationSetupError(RigmapError, ValueError):
    """A method, setting or test data the runner cannot use, with what was expected."""


# --------------------------------------------------------------------------- methods
@dataclass(frozen=True)
class Method:
    """One row of Table 1: how the initial guess is made and how it is refined."""

    name: str
    guess: str  # "script" or "regressor"
    regressor: str | None = None  # "gpr", "nn", "mean" … when guess == "regressor"
    refine: str = "none"  # one of REFINEMENTS
    jacobian: str | None = None  # one of JACOBIANS when refine == "computed_jacobian"

    def __post_init__(self) -> None:
        if self.guess not in GUESSES:
            raise EvaluationSetupError(
                f"method {self.name!r}: guess must be one of {GUESSES}, got {self.guess!r}"
            )
        if (self.guess == "regressor") != (self.regressor is not None):
            raise EvaluationSetupError(
                f"method {self.name!r}: a regressor is needed exactly when the guess is "
                f"'regressor' (guess {self.guess!r}, regressor {self.regressor!r})"
            )
        if self.refine not in REFINEMENTS:
            raise EvaluationSetupError(
                f"method {self.name!r}: refine must be one of {REFINEMENTS}, got {self.refine!r}"
            )
        wants_jacobian = self.refine == "computed_jacobian"
        if wants_jacobian != (self.jacobian in JACOBIANS) or (
            not wants_jacobian and self.jacobian is not None
        ):
            raise EvaluationSetupError(
                f"method {self.name!r}: a computed Jacobian needs jacobian in {JACOBIANS}, "
                f"other refinements none (refine {self.refine!r}, jacobian {self.jacobian!r})"
            )

    @property
    def uses_rig_during_retarget(self) -> bool:
        """Whether the method itself evaluates the rig (and so is slow on a DCC rig)."""
        return self.guess == "script" or self.refine != "none"

    @property
    def refine_label(self) -> str:
        """``none``, ``learned_jacobian``, ``finite_difference`` or ``autodiff``."""
        return self.jacobian if self.refine == "computed_jacobian" else self.refine


FINITE = "finite_difference"

METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("script", "script"),
        Method("gpr", "regressor", "gpr"),
        Method("gpr_learned_jacobian", "regressor", "gpr", "learned_jacobian"),
        Method("gpr_computed_jacobian", "regressor", "gpr", "computed_jacobian", FINITE),
        Method("nn", "regressor", "nn"),
        Method("nn_computed_jacobian", "regressor", "nn", "computed_jacobian", FINITE),
        Method("nn_learned_jacobian", "regressor", "nn", "learned_jacobian"),
        Method("nn_autodiff_jacobian", "regressor", "nn", "computed_jacobian", "autodiff"),
        Method("mean", "regressor", "mean"),  # the yardstick of the scale-free column (ours)
    )
}
#: rows that exist only as their config (conf/method/<name>.yaml): the joint-space network's
#: (issue #15), whose model is fitted by its own stage and whose tuning settings live in the
#: yaml (ConfiguredMethod.tune), not in a Method
CONFIG_ONLY_METHODS = ("nn_joint_space", "nn_joint_space_computed_jacobian", "nn_joint_space_tuned")


def get_method(name: str) -> Method:
    try:
        return METHODS[name]
    except KeyError:
        raise EvaluationSetupError(
            f"unknown method {name!r}; available methods: {', '.join(METHODS)}"
        ) from None


@dataclass(frozen=True)
class RefineSettings:
    """Damped least squares settings: λ, tolerance (cm²), iteration cap, step metric, ranges.

    ``control_scale`` ``"training_std"`` damps the step in training standard
    deviations of the controls (λ in cm per std), ``"none"`` in each control's
    own unit (λ in cm per unit, the literal Eq. 13); ``keep_in_range`` keeps
    refined controls inside their soft ranges (see rigmap.refine, issue #7).
    ``solver`` (block_cholesky | cholesky | svd), ``differences`` (central | forward),
    ``share_every`` and ``jacobian_update`` choose how the step is solved and how a
    computed Jacobian is reused (``rigmap.refine.jacobian_reuse``, issue #16);
    ``sparsity`` (dense | coloured) whether it differences structurally
    independent controls together (``rigmap.refine.sparsity``); ``threads`` the
    torch threads refinement runs on (``None``: torch's own setting); ``traced``
    whether a built-in rig is evaluated by its TorchScript traces (issue #16; true in
    ``conf/refine`` since session 28, while these fields keep the original refinement's
    values, as the solver's and the differences' do).
    """

    damping: float | str = "auto"
    tolerance: float = 1e-4
    max_iterations: int = 10
    control_scale: str = "training_std"
    keep_in_range: bool = True
    solver: str = "cholesky"
    differences: str = "central"
    share_every: int = 1
    jacobian_update: str = "recompute"
    sparsity: str = "dense"
    threads: int | None = 1
    traced: bool = False

    def __post_init__(self) -> None:
        number = isinstance(self.damping, int | float) and np.isfinite(self.damping)
        if self.damping != "auto" and not (number and self.damping >= 0):
            raise EvaluationSetupError(
                f"refine.damping: expected a number >= 0 (cm) or 'auto', got {self.damping!r}"
            )
        if not (isinstance(self.tolerance, int | float) and self.tolerance >= 0):
            raise EvaluationSetupError(
                f"refine.tolerance: expected a number >= 0 (cm²), got {self.tolerance!r}"
            )
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 0:
            raise EvaluationSetupError(
                f"refine.max_iterations: expected an integer >= 0, got {self.max_iterations!r}"
            )
        for flag in ("keep_in_range", "traced"):
            if not isinstance(getattr(self, flag), bool):
                raise EvaluationSetupError(
                    f"refine.{flag}: expected true or false, got {getattr(self, flag)!r}"
                )
        if self.threads is not None and not (isinstance(self.threads, int) and self.threads >= 1):
            raise EvaluationSetupError(
                f"refine.threads: expected an integer >= 1 or null, got {self.threads!r}"
            )
        if not (isinstance(self.share_every, int) and self.share_every >= 1):
            raise EvaluationSetupError(
                f"refine.share_every: expected an integer >= 1, got {self.share_every!r}"
            )
        self._check_choices()

    def _check_choices(self) -> None:
        """Each named option is one of its choices (``refine.<name>: expected one of …``)."""
        from rigmap.refine import DIFFERENCES, SOLVERS, SPARSITIES
        from rigmap.refine.jacobian_reuse import UPDATES

        choices = {"control_scale": CONTROL_SCALES, "solver": SOLVERS,
                   "differences": DIFFERENCES, "jacobian_update": UPDATES,
                   "sparsity": SPARSITIES}  # fmt: skip
        for name, allowed in choices.items():
            value = getattr(self, name)
            if value not in allowed:
                raise EvaluationSetupError(
                    f"refine.{name}: expected one of {allowed}, got {value!r}"
                )

    def reuse(self):
        """The computed Jacobian's reuse policy (``rigmap.refine.JacobianReuse``)."""
        from rigmap.refine import JacobianReuse

        return JacobianReuse(share_every=self.share_every, update=self.jacobian_update)

    @classmethod
    def from_config(cls, config: Mapping[str, Any], method: Method) -> RefineSettings:
        """From a ``refine`` config group (conf/refine/*.yaml) composed for ``method``.

        The group must be the method's refinement (and, for a computed Jacobian,
        name the same Jacobian), so a config never silently runs another method.
        """
        config = dict(config)
        if config.get("name") != method.refine:
            raise EvaluationSetupError(
                f"method {method.name!r} refines with {method.refine!r}, but the refine config "
                f"is {config.get('name')!r}"
            )
        if method.refine == "computed_jacobian" and config.get("jacobian") != method.jacobian:
            raise EvaluationSetupError(
                f"method {method.name!r} uses the {method.jacobian} Jacobian, but refine.jacobian "
                f"is {config.get('jacobian')!r}"
            )
        missing = [k for k in ("damping", "tolerance", "max_iterations") if k not in config]
        if missing:
            raise EvaluationSetupError(f"refine config {method.refine!r} lacks {missing}")
        damping = config["damping"]
        return cls(
            damping=damping if damping == "auto" else float(damping),
            tolerance=float(config["tolerance"]),
            max_iterations=int(config["max_iterations"]),
            control_scale=str(config.get("control_scale", cls.control_scale)),
            keep_in_range=config.get("keep_in_range", cls.keep_in_range),
            solver=str(config.get("solver", cls.solver)),
            differences=str(config.get("differences", cls.differences)),
            share_every=config.get("share_every", cls.share_every),
            jacobian_update=str(config.get("jacobian_update", cls.jacobian_update)),
            sparsity=str(config.get("sparsity", cls.sparsity)),
            threads=config.get("threads", cls.threads),
            traced=config.get("traced", cls.traced),
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "damping": self.damping,
            "tolerance": self.tolerance,
            "max_iterations": self.max_iterations,
            "control_scale": self.control_scale,
            "keep_in_range": self.keep_in_range,
            "solver": self.solver,
            "differences": self.differences,
            "share_every": self.share_every,
            "jacobian_update": self.jacobian_update,
            "sparsity": self.sparsity,
            "threads": self.threads,
            "traced": self.traced,
        }


# --------------------------------------------------------------------------- test data
@dataclass(frozen=True)
class TestClip:
    """One test clip: target poses (cm, COG-relative, COG placement) and the animator's keys."""

    name: str
    frames: np.ndarray  # (N,) the clip's frame numbers
    positions: np.ndarray  # (N, J, 3)
    cog: np.ndarray  # (N, 3)
    cog_rotation: np.ndarray  # (N, 3, 3)
    controls: np.ndarray  # (N, C_used) the animator's values = ground truth

    __test__ = False  # a data class, not a pytest test class

    def __len__(self) -> int:
        return len(self.frames)


@dataclass(frozen=True)
class TestSet:
    """A rig's test clips and the training-corpus std that scales the ground-truth error."""

    rig: str
    clips: list[TestClip]
    control_names: list[str]  # the used controls, rig order
    control_kinds: list[str]
    train_std: np.ndarray  # (C_used,)
    character_height: float | None = None  # the rig's rest height; errors as % of it
    train_poses: np.ndarray | None = None  # (N, 3J + 12) pose rows a fit on the corpus learns
    train_controls: np.ndarray | None = None  # (N, C_used): their controls, row for row

    __test__ = False  # a data class, not a pytest test class

    @property
    def frames(self) -> int:
        return sum(len(c) for c in self.clips)

    def first_frames(self, n: int | None) -> TestSet:
        """The same clips cut to their first ``n`` frames (``None``: unchanged)."""
        if n is None:
            return self
        if int(n) != n or n < 1:
            raise EvaluationSetupError(f"frames per clip: expected an integer >= 1, got {n!r}")
        n = int(n)
        clips = [
            TestClip(
                c.name, c.frames[:n], c.positions[:n], c.cog[:n], c.cog_rotation[:n], c.controls[:n]
            )
            for c in self.clips
        ]
        return TestSet(
            self.rig, clips, self.control_names, self.control_kinds, self.train_std,
            self.character_height, self.train_poses, self.train_controls,
        )  # fmt: skip

    @classmethod
    def load(
        cls,
        rig: Any,
        data: Layout | str | Path,
        *,
        clips: Sequence[str] | None = None,
        split: str = "test",
    ) -> TestSet:
        """Read the rig's poses and corpus of ``split`` and its training corpus.

        ``data`` is a :class:`rigmap.store.Layout` or the rig's data folder
        (``data/<rig>``); ``clips`` picks clips by name (default: all, in file order);
        ``split`` is ``test`` (the library's test clips), ``heldout`` (new takes of the
        training motions) or ``train`` (the training frames: the training error).
        """
        from rigmap.animation.corpus import Corpus
        from rigmap.animation.posing import PoseTable

        layout = _layout_of(data, rig.name)
        used = list(rig.used_controls)
        poses_file, corpus_file = layout.poses(rig.name, split), layout.corpus(rig.name, split)
        poses = PoseTable.read(poses_file, rig=rig.name, n_joints=rig.n_joints, split=split)
        if poses.joint_names != list(rig.joint_names):
            raise EvaluationSetupError(f"{poses_file}: joint names differ from rig {rig.name!r}'s")
        test = Corpus.read(corpus_file, rig=rig.name, control_names=used, split=split)
        train = Corpus.read(
            layout.corpus(rig.name, "train"), rig=rig.name, control_names=used, split="train"
        )
        keys = ["clip", "frame"]
        pose_keys = poses.table[keys].reset_index(drop=True)
        corpus_keys = test.table[keys].reset_index(drop=True)
        if not pose_keys.equals(corpus_keys):
            raise EvaluationSetupError(
                f"{poses_file} and {corpus_file} list different (clip, frame) rows "
                f"({len(pose_keys)} and {len(corpus_keys)} rows); re-run the stage that wrote them"
            )
        names = list(dict.fromkeys(poses.table["clip"]))
        if clips is not None:
            unknown = [c for c in clips if c not in names]
            if unknown or not clips:
                raise EvaluationSetupError(
                    f"{split} clips {unknown or '[]'} not found for rig {rig.name!r}; "
                    f"its {split} clips are {names}"
                )
            names = list(clips)
        positions, cog, rotation = poses.positions(), poses.cog(), poses.cog_rotation()
        truth = test.table[used].to_numpy(dtype=np.float64)
        clip_column = poses.table["clip"].to_numpy()
        frame_column = poses.table["frame"].to_numpy()
        test_clips = []
        for name in names:
            rows = np.flatnonzero(clip_column == name)
            test_clips.append(
                TestClip(
                    name,
                    frame_column[rows].astype(np.int64),
                    positions[rows],
                    cog[rows],
                    rotation[rows],
                    truth[rows],
                )
            )
        kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
        std = control_std(train.table[used].to_numpy(dtype=np.float64))
        train_poses, train_controls = _training_rows(rig, layout)
        return cls(
            rig.name, test_clips, used, kinds, std, rig.rest_height(), train_poses, train_controls
        )  # fmt: skip


def _training_rows(rig: Any, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """The pose rows and controls a fit on the corpus learns from (the corpus frames and the
    rest pose, as the fit stage reads them): what a test frame's novelty is measured to."""
    from rigmap.regression.fitting import load_training_data

    data = load_training_data(rig, layout.data, "none")
    return data.features, data.controls


def _layout_of(data: Layout | str | Path, rig: str) -> Layout:
    """``data`` as a Layout; a folder must be the rig's own (``<data root>/<rig>``)."""
    if isinstance(data, Layout):
        return data
    folder = Path(data)
    if folder.name != rig:
        raise EvaluationSetupError(
            f"test data folder {folder}: expected the rig's data folder <data>/{rig}, or a Layout"
        )
    return Layout(data=folder.parent)


# --------------------------------------------------------------------------- results
@dataclass
class MethodEvaluation:
    """A method's scores (``result``) and the control curves it produced."""

    result: MethodResult
    controls: pd.DataFrame  # clip, frame, one column per used control
    initial_joint_error: dict[str, float] = field(default_factory=dict)  # per clip, refined only


# --------------------------------------------------------------------------- runner
def run_method(
    rig: Any,
    method: Method | str,
    test_set: TestSet,
    *,
    regressor: Any = None,
    learned_jacobian: Any = None,
    refine: RefineSettings | None = None,
    sampler: str = "none",
    kernel: str | None = None,
    warmup_frames: int = 1,
    extra: Mapping[str, Any] | None = None,
    progress: bool = False,
) -> MethodEvaluation:
    """Retarget every clip of ``test_set`` with ``method``; time, count and score it.

    ``regressor`` is the fitted inverse mapping (features -> used controls) for
    regressor methods; ``learned_jacobian`` the ``LearnedJacobian`` for
    learned-Jacobian refinement; ``refine`` the damped-least-squares settings
    for refined methods. ``sampler`` and ``kernel`` label the result.
    """
    method = get_method(method) if isinstance(method, str) else method
    _check_inputs(rig, method, test_set, regressor, learned_jacobian, refine)
    counting = ScriptCountingRig(rig) if method.guess == "script" else CountingRig(rig)
    retarget = _Retargeter(
        counting, method, regressor, learned_jacobian, refine, test_set.train_std
    )
    novelty = _novelty_of(regressor, test_set, rig)
    clip_results, curves, initial, iterations, warmup = [], [], {}, {}, {}
    for clip in test_set.clips:
        (Y_used, refined), timing = run_timed(
            partial(retarget, clip), np.arange(len(clip)), warmup_frames=warmup_frames, rig=counting
        )
        result, truth = _score_clip(rig, clip, test_set, Y_used, timing)
        if novelty is not None:  # after the clock: a diagnostic, not part of the method
            rows = _pose_rows(rig, clip.name, clip.positions, clip.cog, clip.cog_rotation)
            result.novelty_per_frame = novelty(rows)
        clip_results.append(result)
        warmup[clip.name] = {"seconds": timing.warmup_seconds, "frames": timing.warmup_frames}
        if refined is not None:
            initial[clip.name] = float(refined.initial_joint_error.mean())
            iterations[clip.name] = float(refined.iterations.mean())
        table = pd.DataFrame(Y_used, columns=test_set.control_names)
        table.insert(0, "frame", clip.frames)
        table.insert(0, "clip", clip.name)
        curves.append(table)
        if progress:
            _print_clip(rig, test_set, method, result)
    context = _method_context(method, kernel, refine, test_set, warmup, initial, iterations)
    context.update(extra or {})
    result = MethodResult(
        test_set.rig,
        method.name,
        sampler,
        clip_results,
        length_unit=str(getattr(rig, "length_unit", "cm")),
        warmup_frames=int(warmup_frames),
        skipped_controls=truth.skipped,
        extra=context,
        character_height=test_set.character_height,
    )
    controls = pd.concat(curves, ignore_index=True)
    return MethodEvaluation(result, controls, initial)


def _novelty_of(regressor: Any, test_set: TestSet, rig: Any):
    """``pose rows -> novelty per frame`` in the regressor's own inputs, or None (script).

    Measured to the rows the mapping learned from: the training corpus, and for a regressor
    that draws poses of its own (the joint-space network) those too.
    """
    if regressor is None or test_set.train_poses is None:
        return None
    placement = getattr(regressor, "placement", None)
    inputs = placement.inputs if placement is not None else np.asarray  # a bare regressor
    reference = inputs(test_set.train_poses)
    learned = getattr(getattr(regressor, "regressor", None), "learned_inputs", None)
    if learned is not None and placement is not None and test_set.train_controls is not None:
        targets = placement.targets(test_set.train_controls, test_set.train_poses)
        reference = learned(reference, targets, rig=rig, placement=placement)
    measure = Novelty.from_training(reference, rig.n_joints)
    return lambda rows: measure.distances(inputs(rows))


def _pose_rows(rig, clip_name: str, positions, cog, rotation) -> np.ndarray:
    """A test clip's frames as the pose rows a regressor takes."""
    from rigmap.regression.features import inverse_features

    return inverse_features(
        positions, cog, rotation, n_joints=rig.n_joints,
        where=f"test clip {clip_name!r} of rig {rig.name!r}",
    )  # fmt: skip


def _score_clip(rig, clip: TestClip, test_set: TestSet, Y_used: np.ndarray, timing):
    """The clip's errors (rig evaluations that score are not timed, not counted)."""
    X_pred = rig.evaluate(rig.expand_used(Y_used))
    truth = ground_truth_error(
        Y_used,
        clip.controls,
        test_set.train_std,
        test_set.control_kinds,
        names=test_set.control_names,
    )
    result = ClipResult(
        clip.name,
        joint_error(X_pred, clip.positions).per_frame,
        truth.per_frame,
        total_time_s=timing.seconds,
        rig_evaluations=timing.rig.poses,
        rig_calls=timing.rig.calls,
        frame_numbers=clip.frames,
    )
    return result, truth


def _print_clip(rig, test_set: TestSet, method: Method, result: ClipResult) -> None:
    summary = result.summary()
    print(
        f"  {test_set.rig} {method.name} {result.clip!r}: joint error "
        f"{summary['joint_error']:.4g} {getattr(rig, 'length_unit', 'cm')}², "
        f"ground truth {summary['ground_truth_error']:.4g}, "
        f"{summary['total_time_s']:.3g} s ({summary['fps']:.4g} fps), "
        f"{summary['rig_evaluations']} rig evaluations",
        flush=True,
    )


def _method_context(method, kernel, refine, test_set, warmup, initial, iterations) -> dict:
    """What the metrics JSON's ``extra`` says about the method, its timing and refinement."""
    context: dict[str, Any] = {
        "guess": method.guess,
        "regressor": method.regressor,
        "kernel": kernel,
        "refine": method.refine,
        "jacobian": method.jacobian,
        "refine_settings": refine.to_dict() if refine is not None else None,
        "timing_scope": TIMING_SCOPE,
        "warmup": warmup,
        "unused_controls": "rig defaults",
    }
    if initial:
        frames = {c.name: len(c) for c in test_set.clips}
        total = sum(frames.values())
        context["initial_joint_error"] = {
            "average": sum(initial[n] * frames[n] for n in initial) / total,
            "clips": initial,
        }
        context["mean_iterations"] = {
            "average": sum(iterations[n] * frames[n] for n in iterations) / total,
            "clips": iterations,
        }
    return context


class ScriptCountingRig(CountingRig):
    """A ``CountingRig`` that also counts a script's read-backs and Blender constraint solves."""

    def world_transforms(self, Y: Any) -> Any:
        out = self.wrapped.world_transforms(Y)
        self._record(Y)
        return out

    def constraint_retarget(self, positions: Any, cog: Any, cog_rotation: Any) -> Any:
        """A Blender rig's constraint solve: one rig evaluation per target frame."""
        out = self.wrapped.constraint_retarget(positions, cog, cog_rotation)
        self._record(positions)
        return out


class _Retargeter:
    """``(clip, frames) -> (Y_used, RefineResult | None)``: the method itself, what is timed."""

    def __init__(self, rig, method, regressor, learned_jacobian, refine, train_std):
        self.rig = rig
        self.method = method
        self.regressor = regressor
        self.learned_jacobian = learned_jacobian
        self.refine = refine
        self.train_std = train_std  # (C_used,) the training corpus's, as the metric uses

    def __call__(self, clip: TestClip, frames: np.ndarray):
        from rigmap.refine import ComputedJacobian, PredictedJacobian, damped_least_squares

        positions, cog = clip.positions[frames], clip.cog[frames]
        rotation = clip.cog_rotation[frames]
        if self.method.guess == "script":
            from rigmap.retarget.script import script_retarget

            Y_used = script_retarget(self.rig, positions, cog, rotation).Y_used
        else:
            features = self._features(clip, positions, cog, rotation)
            Y_used = np.asarray(self.regressor.predict(features), dtype=np.float64)
        if self.method.refine == "none":
            return Y_used, None
        if self.method.refine == "computed_jacobian":
            source = ComputedJacobian(
                self.rig,
                self.method.jacobian,
                self.refine.differences,
                sparsity=self.refine.sparsity,
            )
        else:  # predicted once per frame from its features: no rig evaluation
            features = self._features(clip, positions, cog, rotation)
            source = PredictedJacobian(self.learned_jacobian, features)
        refined = damped_least_squares(
            self.rig,
            Y_used,
            positions,
            source,
            damping=self.refine.damping,
            tolerance=self.refine.tolerance,
            max_iterations=self.refine.max_iterations,
            control_scale=self.train_std if self.refine.control_scale == "training_std" else None,
            keep_in_range=self.refine.keep_in_range,
            solver=self.refine.solver,
            reuse=self.refine.reuse(),
            threads=self.refine.threads,
            traced=self.refine.traced,
        )
        return refined.Y_used, refined

    def _features(self, clip, positions, cog, rotation) -> np.ndarray:
        return _pose_rows(self.rig, clip.name, positions, cog, rotation)


def _check_inputs(rig, method, test_set, regressor, learned_jacobian, refine) -> None:
    if test_set.rig != rig.name:
        raise EvaluationSetupError(
            f"test set is for rig {test_set.rig!r}, but the rig is {rig.name!r}"
        )
    if method.guess == "regressor" and regressor is None:
        raise EvaluationSetupError(
            f"method {method.name!r} needs a fitted {method.regressor} inverse mapping "
            "(regressor=...); got none"
        )
    if method.guess == "script" and regressor is not None:
        raise EvaluationSetupError(f"method {method.name!r} takes no regressor; one was given")
    if method.refine == "learned_jacobian" and learned_jacobian is None:
        raise EvaluationSetupError(
            f"method {method.name!r} needs a learned Jacobian (learned_jacobian=...); got none"
        )
    if method.refine != "none" and refine is None:
        raise EvaluationSetupError(
            f"method {method.name!r} refines: pass refine=RefineSettings(...) (conf/refine)"
        )
    if method.refine == "none" and refine is not None:
        raise EvaluationSetupError(
            f"method {method.name!r} does not refine, but refine settings were given"
        )
    if method.jacobian == "autodiff" and not getattr(rig, "differentiable", False):
        raise EvaluationSetupError(
            f"method {method.name!r} needs autodiff, but rig {rig.name!r} is not differentiable"
        )
