"""A tiny linear "rig" for the latent tests: its influence per control is known exactly."""

from __future__ import annotations

import numpy as np

from rigmap.rigs import Control, ControlTable, Pose, Rig


class LinearRig(Rig):
    """``x = A y``: every control moves the joints along one fixed column of ``A`` (cm)."""

    def __init__(self, A: np.ndarray, used: list[bool], lower=-3.0, upper=3.0):
        self.name = "linear"
        self.A = np.asarray(A, dtype=np.float64)
        self.controls = ControlTable(
            [Control(f"c{i}", "scalar", 0.0, lower, upper, u, "all") for i, u in enumerate(used)]
        )
        self.joint_names = [f"j{k}" for k in range(self.A.shape[0] // 3)]
        self.parents = np.full(len(self.joint_names), -1)

    def _pose(self, Y):
        Y = np.asarray(Y, dtype=np.float64)
        positions = (Y @ self.A.T).reshape(len(Y), -1, 3)
        return Pose(positions, np.zeros((len(Y), 3)), np.tile(np.eye(3), (len(Y), 1, 1)))
