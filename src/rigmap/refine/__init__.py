"""Refinement of predicted controls: rig Jacobians and damped least squares (§4.3)."""

from rigmap.refine.jacobian import JACOBIAN_METHODS, jacobian

__all__ = ["JACOBIAN_METHODS", "jacobian"]
