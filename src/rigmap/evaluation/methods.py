"""The methods of Table 1, the test set and the runner, under the names callers import.

Each lives in a module of its own concept: :mod:`~rigmap.evaluation.method` (a method as a
guess and a refiner, built from ``conf/method``), :mod:`~rigmap.evaluation.refine_settings`,
:mod:`~rigmap.evaluation.clips` (the test clips), :mod:`~rigmap.evaluation.runner` (timing
and scoring), :mod:`~rigmap.evaluation.retargeter` and :mod:`~rigmap.evaluation.checks`.
"""

from rigmap.evaluation.checks import EvaluationSetupError
from rigmap.evaluation.clips import TestClip, TestSet
from rigmap.evaluation.method import (
    JACOBIANS,
    ComputedJacobianRefinement,
    Guess,
    LearnedJacobianRefinement,
    Method,
    NoRefinement,
    Refiner,
    RegressorGuess,
    ScriptGuess,
    get_method,
    method_catalog,
)
from rigmap.evaluation.refine_settings import CONTROL_SCALES, RefineSettings
from rigmap.evaluation.runner import TIMING_SCOPE, MethodEvaluation, run_method
from rigmap.evaluation.timing import ScriptCountingRig

__all__ = [
    "CONTROL_SCALES",
    "JACOBIANS",
    "TIMING_SCOPE",
    "ComputedJacobianRefinement",
    "EvaluationSetupError",
    "Guess",
    "LearnedJacobianRefinement",
    "Method",
    "MethodEvaluation",
    "NoRefinement",
    "RefineSettings",
    "Refiner",
    "RegressorGuess",
    "ScriptCountingRig",
    "ScriptGuess",
    "TestClip",
    "TestSet",
    "get_method",
    "method_catalog",
    "run_method",
]
