"""A fitted model folder that lost its placement.json is refused, not loaded bare.

Issue 20, defect 10: a deleted ``placement.json`` silently loaded the bare regressor,
which then read pose rows as if they were its placement-free inputs.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.regression import GaussianProcessRegressor, ModelFileError, load_regressor
from rigmap.regression.mapping import InverseMapping
from rigmap.regression.placement import Placement


def test_a_fit_folder_without_its_placement_is_refused(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.normal(size=(20, 3 * 2 + 12))
    Y = rng.normal(size=(20, 3))
    gpr = GaussianProcessRegressor(n_points=10, n_length_scales=3, cv_splits=2, progress=False)
    mapping = InverseMapping(gpr, Placement(n_joints=2, n_controls=3)).fit(X, Y)
    folder = mapping.save(tmp_path / "gpr-none-multiquadric")
    (folder / "fit.json").write_text("{}\n")
    np.testing.assert_allclose(load_regressor(folder).predict(X[:4]), mapping.predict(X[:4]))
    (folder / "placement.json").unlink()
    with pytest.raises(ModelFileError, match=r"gpr-none-multiquadric: placement\.json is missing"):
        load_regressor(folder)
