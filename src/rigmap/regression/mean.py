"""The mean predictor: every frame gets the training corpus's mean controls.

It is the yardstick that makes an error comparable across rigs and with the paper
(issue #15): a method's error divided by this predictor's on the same test frames
says how much of the motion it recovers, whatever the character's size or unit. It
sits behind the same placement as every regressor, so the root channels still come
from the target's COG and only the pose is the average one. scikit-learn's
``DummyRegressor(strategy="mean")`` is the fit; this class only gives it rigmap's
files and fingerprint.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sklearn.dummy import DummyRegressor

from rigmap.regression.base import Regressor
from rigmap.regression.fingerprint import ModelFingerprint
from rigmap.regression.validation import check_training_data


class MeanRegressor(Regressor):
    """``predict(X)`` = the mean of the training targets, for every row of ``X``."""

    name = "mean"
    saved_arrays = ("mean",)

    def fit(
        self, X: Any, Y: Any, *, rig_name: str | None = None, control_names: Any = None
    ) -> MeanRegressor:
        X, Y = check_training_data(X, Y, "MeanRegressor")
        dummy = DummyRegressor(strategy="mean").fit(X, Y)
        self.mean_ = np.asarray(dummy.constant_, dtype=np.float64).reshape(Y.shape[1])
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], Y.shape[1], rig_name, control_names)
        return self

    def predict(self, X: Any) -> np.ndarray:
        X, single = self.fingerprint_.check_inputs(X, "MeanRegressor")
        Y = np.repeat(self.mean_[None], len(X), axis=0)
        return Y[0] if single else Y

    def describe_plan(self, rows: int) -> str:
        return f"averaging the targets of {rows} rows (the mean predictor)"
