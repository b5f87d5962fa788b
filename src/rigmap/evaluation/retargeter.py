"""The method itself, what the clock covers: a clip's frames to controls by guess and refiner."""

from __future__ import annotations

import contextlib
from typing import Any

import numpy as np

from rigmap.evaluation.clips import TestClip


class Retargeter:
    """``(clip, frames) -> (Y_used, RefineResult | None)`` for one method and its models."""

    def __init__(self, rig, method, regressor, learned_jacobian, refine, train_std):
        self.rig = rig
        self.method = method
        self.regressor = regressor
        self.learned_jacobian = learned_jacobian
        self.refine = refine  # RefineSettings overriding the method's own, or None
        self.train_std = train_std  # (C_used,) the training corpus's, as the metric uses

    def __call__(self, clip: TestClip, frames: np.ndarray):
        positions, cog = clip.positions[frames], clip.cog[frames]
        rotation = clip.cog_rotation[frames]

        def features() -> np.ndarray:  # computed when a guess or a refiner asks (inside the clock)
            return pose_rows(self.rig, clip.name, positions, cog, rotation)

        guess = self.method.guess(self.rig, self.regressor, positions, cog, rotation, features)
        learned, std = self.learned_jacobian, self.train_std
        return self.method.refiner(self.rig, guess, positions, features, learned, std, self.refine)

    def warm_up(self, clip: TestClip, frames: np.ndarray):
        """The untimed warm-up call: as a call, but a regressor that tunes itself on every
        call (``TunedOnTarget``) tunes for a few steps only: the warm-up pays one-time
        costs (first calls, allocations), not a second tuning whose result is discarded."""
        warming = getattr(self.regressor, "warming_up", None)
        with warming() if warming is not None else contextlib.nullcontext():
            return self(clip, frames)


def pose_rows(rig: Any, clip_name: str, positions, cog, rotation) -> np.ndarray:
    """A test clip's frames as the pose rows a regressor takes."""
    from rigmap.regression.features import inverse_features

    where = f"test clip {clip_name!r} of rig {rig.name!r}"
    return inverse_features(positions, cog, rotation, n_joints=rig.n_joints, where=where)
