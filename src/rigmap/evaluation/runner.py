"""The runner that scores a method on a rig's test clips (paper §6.1).

``run_method`` retargets every test clip, one clip per timed pass: the clock
covers the whole method from the clip's poses to its controls — features,
prediction, every rig evaluation refinement makes — after an untimed warm-up
on the clip's first frames (one-off costs: thread pools, caches, torch
kernel selection). The rig evaluations that *score* the result (joint error)
are measurement, not method, and are neither timed nor counted. Controls the
method does not predict (the rig's unused ones) stay at their defaults.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import pandas as pd

from rigmap.evaluation.checks import EvaluationSetupError, check_inputs
from rigmap.evaluation.clips import TestClip, TestSet
from rigmap.evaluation.method import Method, get_method
from rigmap.evaluation.metrics import ClipResult, MethodResult, ground_truth_error, joint_error
from rigmap.evaluation.novelty import Novelty
from rigmap.evaluation.refine_settings import RefineSettings
from rigmap.evaluation.retargeter import Retargeter, pose_rows
from rigmap.evaluation.timing import run_timed

#: what the clock covers, written into every metrics JSON
TIMING_SCOPE = (
    "per clip, from its target poses to its controls: input features, the script or "
    "regressor, and refinement with every rig evaluation it makes; the rig evaluations "
    "that score the result (joint error) are not timed or counted"
)


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
    learned-Jacobian refinement; ``refine`` damped-least-squares settings that replace
    the method's own (``None``: the method's). ``sampler`` and ``kernel`` label the result.
    """
    method = get_method(method) if isinstance(method, str) else method
    check_inputs(rig, method, test_set, regressor, learned_jacobian)
    if method.refine == "none" and refine is not None:
        raise EvaluationSetupError(
            f"method {method.name!r} does not refine, but refine settings were given"
        )
    refine = refine if refine is not None else method.refine_settings
    counting = method.guess.counting_rig(rig)
    retarget = Retargeter(counting, method, regressor, learned_jacobian, refine, test_set.train_std)
    novelty = _novelty_of(regressor, test_set, rig)
    clip_results, curves, initial, iterations, warmup = [], [], {}, {}, {}
    for clip in test_set.clips:
        (Y_used, refined), timing = run_timed(
            partial(retarget, clip),
            np.arange(len(clip)),
            warmup_frames=warmup_frames,
            rig=counting,
            warmup=partial(retarget.warm_up, clip),
        )
        result, truth = _score_clip(rig, clip, test_set, Y_used, timing)
        if novelty is not None:  # after the clock: a diagnostic, not part of the method
            rows = pose_rows(rig, clip.name, clip.positions, clip.cog, clip.cog_rotation)
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
        "guess": method.guess.kind,
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
