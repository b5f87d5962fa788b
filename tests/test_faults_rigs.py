"""Rigs refuse what used to pass silently: NaN poses from huge controls, zero workers.

Issue 20, defect 9: finite but huge controls gave all-NaN poses with no error, and a
Blender rig's ``workers: 0`` was ignored.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.rigs import RigInputError, load
from rigmap.rigs.blender.rigify import build_rigify_human


def test_huge_controls_that_overflow_the_rig_are_named():
    rig = load("biped")
    Y = rig.default_controls(3)
    Y[1:, rig.controls.index("cog.ty")] = 1e308  # finite, far outside its soft range
    # (the body flies away from the planted IK feet and the leg solve overflows)
    np.testing.assert_array_equal(np.isfinite(rig.evaluate(Y[:1])), True)
    with pytest.raises(
        RigInputError, match=r"'biped' gave NaN or infinite .* 2 of 3 .*first row 1"
    ):
        rig.evaluate(Y)


@pytest.mark.blender
@pytest.mark.parametrize("workers", [0, -2, 1.5, True])
def test_a_blender_rig_with_no_workers_is_refused(workers):
    with pytest.raises(RigInputError, match="workers must be a whole number >= 1"):
        build_rigify_human(workers=workers)
