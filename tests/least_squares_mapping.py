"""A tiny real inverse mapping for tracking tests: ridge-regularised linear least squares.

It has the scikit-learn-style contract the real regressors have — ``fit``,
``predict(X (N, D)) -> (N, C)``, ``save(folder)`` and a ``load(folder)``
classmethod — so MLflow logging can be tested without GPR or NN.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np


class LeastSquaresMapping:
    """``y = [x, 1] W`` with ``W`` from ridge-regularised normal equations on standardised x."""

    def __init__(self, ridge: float = 1e-3):
        self.ridge = ridge

    def fit(self, X: np.ndarray, Y: np.ndarray) -> LeastSquaresMapping:
        X, Y = np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64)
        self.x_mean_, self.x_std_ = X.mean(axis=0), X.std(axis=0) + 1e-12
        A = np.c_[(X - self.x_mean_) / self.x_std_, np.ones(len(X))]
        self.weights_ = np.linalg.solve(A.T @ A + self.ridge * np.eye(A.shape[1]), A.T @ Y)
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != len(self.x_mean_):
            raise ValueError(f"expected inputs (N, {len(self.x_mean_)}), got {X.shape}")
        return np.c_[(X - self.x_mean_) / self.x_std_, np.ones(len(X))] @ self.weights_

    def save(self, folder: str | os.PathLike) -> Path:
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        np.savez(folder / "weights.npz", x_mean=self.x_mean_, x_std=self.x_std_, W=self.weights_)
        (folder / "params.json").write_text(json.dumps({"ridge": self.ridge}))
        return folder

    @classmethod
    def load(cls, folder: str | os.PathLike) -> LeastSquaresMapping:
        folder = Path(folder)
        model = cls(**json.loads((folder / "params.json").read_text()))
        with np.load(folder / "weights.npz") as arrays:
            model.x_mean_, model.x_std_ = arrays["x_mean"], arrays["x_std"]
            model.weights_ = arrays["W"]
        return model
