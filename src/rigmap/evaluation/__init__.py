"""Evaluation of inverse rig mappings (paper §6.1): errors, honest timing, methods and runs.

- :mod:`~rigmap.evaluation.metrics`: joint and ground-truth errors, a method's result file;
- :mod:`~rigmap.evaluation.timing`: the clock and the rig-evaluation counter;
- :mod:`~rigmap.evaluation.method`: a method as a guess and a refiner, built from conf/method;
- :mod:`~rigmap.evaluation.refine_settings`: the damped-least-squares settings (conf/refine);
- :mod:`~rigmap.evaluation.clips`: a rig's test clips; :mod:`~rigmap.evaluation.checks`: checks;
- :mod:`~rigmap.evaluation.runner` (and ``retargeter``): a method timed and scored on them;
- :mod:`~rigmap.evaluation.methods`: all of these under the names callers import;
- :mod:`~rigmap.evaluation.jobs`: the runs of an evaluation set and their files;
- :mod:`~rigmap.evaluation.fitted_models`: the model folders an evaluation reads;
- :mod:`~rigmap.evaluation.evaluate`: the evaluate stage's work on plain objects;
- :mod:`~rigmap.evaluation.mlflow_runs`: its parent and child MLflow runs;
- :mod:`rigmap.app.evaluate` (the application layer): the same from a composed config.
"""

from rigmap.evaluation.evaluate import EvaluationSettings, evaluate, evaluate_job
from rigmap.evaluation.fitted_models import FittedModels
from rigmap.evaluation.jobs import EVALUATION_SETS, EvaluationJob, evaluation_jobs
from rigmap.evaluation.methods import (
    EvaluationSetupError,
    Method,
    MethodEvaluation,
    RefineSettings,
    ScriptCountingRig,
    TestClip,
    TestSet,
    get_method,
    run_method,
)
from rigmap.evaluation.metrics import (
    ClipResult,
    FrameErrors,
    GroundTruthError,
    MethodResult,
    MetricInputError,
    control_std,
    ground_truth_error,
    joint_error,
    write_per_frame_csv,
)
from rigmap.evaluation.timing import CountingRig, RigEvaluationCount, Stopwatch, Timing, run_timed

__all__ = [
    "EVALUATION_SETS",
    "ClipResult",
    "CountingRig",
    "EvaluationJob",
    "EvaluationSettings",
    "EvaluationSetupError",
    "FittedModels",
    "FrameErrors",
    "GroundTruthError",
    "Method",
    "MethodEvaluation",
    "MethodResult",
    "MetricInputError",
    "RefineSettings",
    "RigEvaluationCount",
    "ScriptCountingRig",
    "Stopwatch",
    "TestClip",
    "TestSet",
    "Timing",
    "control_std",
    "evaluate",
    "evaluate_job",
    "evaluation_jobs",
    "get_method",
    "ground_truth_error",
    "joint_error",
    "run_method",
    "run_timed",
    "write_per_frame_csv",
]
