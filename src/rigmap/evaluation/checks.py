"""What the runner checks before a method runs: the rig, the test set and the models it needs."""

from __future__ import annotations

from typing import Any

from rigmap.errors import RigmapError


class EvaluationSetupError(RigmapError, ValueError):
    """A method, setting or test data the runner cannot use, with what was expected."""


def check_inputs(rig: Any, method: Any, test_set: Any, regressor: Any, learned_jacobian: Any):
    """One clear error naming the method when its rig, test set or models do not fit it."""
    if test_set.rig != rig.name:
        raise EvaluationSetupError(
            f"test set is for rig {test_set.rig!r}, but the rig is {rig.name!r}"
        )
    method.guess.check(method.name, regressor)
    method.refiner.check(method.name, rig, learned_jacobian)
