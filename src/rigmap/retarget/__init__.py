"""Retargeting without learning: the paper's hand-written "Maya script" baseline (§6.1)."""

from rigmap.retarget.euler import euler_to_matrix, matrix_to_euler
from rigmap.retarget.script import (
    NoRetargetScriptError,
    ScriptResult,
    script_for,
    script_retarget,
    scripted_rigs,
)

__all__ = [
    "NoRetargetScriptError",
    "ScriptResult",
    "euler_to_matrix",
    "matrix_to_euler",
    "script_for",
    "script_retarget",
    "scripted_rigs",
]
