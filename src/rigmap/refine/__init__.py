"""Refinement of predicted controls: rig Jacobians and damped least squares (§4.3)."""

from rigmap.refine.block_cholesky import BlockCholeskyStep, block_structure
from rigmap.refine.damped_least_squares import RefineResult, damped_least_squares
from rigmap.refine.damping import chiaverini_damping, smallest_singular_value
from rigmap.refine.jacobian import DIFFERENCES, JACOBIAN_METHODS, jacobian
from rigmap.refine.jacobian_reuse import JacobianReuse
from rigmap.refine.normal_equations import SOLVERS, Damping
from rigmap.refine.solvers import damped_solver
from rigmap.refine.sources import (
    SPARSITIES,
    ComputedJacobian,
    JacobianSource,
    PredictedJacobian,
)
from rigmap.refine.sparsity import ColumnColouring, rig_colouring

__all__ = [
    "DIFFERENCES",
    "JACOBIAN_METHODS",
    "SOLVERS",
    "SPARSITIES",
    "BlockCholeskyStep",
    "ColumnColouring",
    "ComputedJacobian",
    "Damping",
    "JacobianReuse",
    "JacobianSource",
    "PredictedJacobian",
    "RefineResult",
    "block_structure",
    "chiaverini_damping",
    "damped_least_squares",
    "damped_solver",
    "jacobian",
    "rig_colouring",
    "smallest_singular_value",
]
