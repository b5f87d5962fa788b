"""Refinement of predicted controls: rig Jacobians and damped least squares (§4.3)."""

from rigmap.refine.damped_least_squares import (
    ComputedJacobian,
    PredictedJacobian,
    RefineResult,
    chiaverini_damping,
    damped_least_squares,
)
from rigmap.refine.jacobian import JACOBIAN_METHODS, jacobian

__all__ = [
    "JACOBIAN_METHODS",
    "ComputedJacobian",
    "PredictedJacobian",
    "RefineResult",
    "chiaverini_damping",
    "damped_least_squares",
    "jacobian",
]
