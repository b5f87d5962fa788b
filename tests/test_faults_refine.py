"""Refinement and Jacobians refuse input that used to give silent NaN or a raw reshape error.

Issue 20, defect 7 (an empty batch in ``damped_least_squares`` failed with "cannot reshape
array of size 0") and defect 9 (``jacobian(step=0)`` returned NaN; ``tolerance=nan``
returned the start as converged).
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.refine import ComputedJacobian, damped_least_squares, jacobian
from rigmap.rigs import RigInputError, load


@pytest.fixture(scope="module")
def face():
    return load("face")


def test_an_empty_batch_is_named(face):
    used = face.controls.used_indices
    with pytest.raises(RigInputError, match=r"face.*no frames to refine \(an empty batch\)"):
        damped_least_squares(face, np.zeros((0, len(used))), np.zeros((0, face.n_joints, 3)),
                             ComputedJacobian(face))  # fmt: skip


@pytest.mark.parametrize("tolerance", [float("nan"), -1.0, float("inf")])
def test_a_tolerance_that_is_no_number_is_refused(face, tolerance):
    rng = np.random.default_rng(0)
    Y = face.default_controls(2)
    Y[:, face.controls.used_indices] += rng.uniform(0, 0.3, (2, len(face.used_controls)))
    target = face.evaluate(Y)
    start = face.default_controls(2)[:, face.controls.used_indices]
    with pytest.raises(RigInputError, match="tolerance must be a finite number >= 0"):
        damped_least_squares(face, start, target, ComputedJacobian(face), tolerance=tolerance)


@pytest.mark.parametrize("step", [0.0, -1e-6, float("nan")])
def test_a_step_that_cannot_difference_is_refused(face, step):
    with pytest.raises(RigInputError, match="jacobian step must be a finite number > 0"):
        jacobian(face, face.default_controls(2), step=step)
