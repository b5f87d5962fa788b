"""What the joint-space network trains on, and its cost: drawn poses and the rig in the loop.

:func:`draw_training_controls` draws poses beyond the corpus (the corpus alone
covers a sliver of what test motion does: issue #15 found 85-100 % of the
extreme test frames more than 3 training stds outside it). :func:`joint_space_cost`
is the cost of :mod:`rigmap.regression.joint_space_network` on one minibatch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from rigmap.regression.features import inverse_features
from rigmap.regression.normalisation import column_scale
from rigmap.regression.rig_forward import PlacedRigForward


def pose_training_draws(rig, placement, controls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Used ``controls`` (:func:`draw_training_controls`) posed by ``rig``: their placement
    inputs and targets, row for row."""
    if not len(controls):
        return np.empty((0, placement.input_width)), controls
    pose = rig.pose(rig.expand_used(controls))
    where = f"poses drawn for joint-space training of rig {rig.name!r}"
    features = inverse_features(
        np.asarray(pose.positions),
        np.asarray(pose.cog),
        np.asarray(pose.cog_rotation),
        n_joints=rig.n_joints,
        where=where,
    )
    return placement.inputs(features, where), placement.targets(controls, features, where)


def draw_training_controls(
    rig,
    placement,
    Y_targets: np.ndarray,
    n_gaussian: int,
    scale: float,
    n_wide: int,
    rng,
    n_local: int = 0,
    local_scale: float = 2.0,
) -> np.ndarray:
    """``n_gaussian`` PCA-Gaussian draws around ``Y_targets``, ``n_local`` per-control
    draws (:func:`local_draws`) and ``n_wide`` uniform draws over the soft ranges: used
    controls ``(N, C_used)``, in that order (wide last), not posed.

    Draws are clamped into the soft ranges (the network's outputs cannot leave them, so a
    pose made outside them could not be reproduced). Root channels are zero.
    """
    from rigmap.sampling import PCAGaussianSampler, UniformSampler
    from rigmap.sampling.clamping import clamp_to_limits

    used = rig.controls.used_indices
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    root = [c.index for c in placement.channels]
    base = np.array(Y_targets, dtype=np.float64)
    base[:, root] = 0.0
    drawn = []
    if n_gaussian:
        gaussian = PCAGaussianSampler(scale=scale).fit(base).sample(n_gaussian, rng)
        drawn.append(clamp_to_limits(gaussian, lower, upper, copy=False).values)
    if n_local:
        pool = np.concatenate([base, *drawn])
        local = local_draws(pool, base.std(axis=0), local_scale, n_local, rng)
        drawn.append(clamp_to_limits(local, lower, upper, copy=False).values)
    if n_wide:
        drawn.append(UniformSampler("soft", lower, upper).fit(base).sample(n_wide, rng))
    if not drawn:
        return np.empty((0, len(used)))
    controls = np.concatenate(drawn)
    controls[:, root] = 0.0
    return controls


def local_draws(pool: np.ndarray, std: np.ndarray, scale: float, n: int, rng) -> np.ndarray:
    """``n`` rows of ``pool`` (drawn with replacement), each control moved by its own
    Gaussian noise of ``scale`` x its ``std``: a Gaussian kernel density with a diagonal
    bandwidth over the pool.

    Why (ours, issue #15): the extreme test clips leave the corpus one part at a time (the
    quadruped's ears held at 4 corpus stds while its legs walk), which the PCA draws, tied
    to the corpus's correlations, do not reach. Written here because scikit-learn's
    ``KernelDensity.sample`` takes one bandwidth for every column.
    """
    rows = pool[rng.integers(0, len(pool), int(n))]
    return rows + rng.standard_normal(rows.shape) * (float(scale) * np.asarray(std))


def float32_tensor(a) -> torch.Tensor:
    """A contiguous float32 tensor of ``a``: the networks train in float32."""
    return torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32))


@dataclass
class JointSpaceData:
    """Every training row as float32 tensors, and the scales that make the cost unit-free.

    ``known``: rows whose controls are the animators' (or a sampler's), where the control
    term applies in the joint-space phase; ``natural``: rows whose controls the
    control-space phase regresses (the known rows and the draws around the corpus; a wide
    draw's controls are a random answer among many for its pose, so it gets the joint
    term only); ``joint_scale``: the mean variance of a joint
    coordinate over those rows (cm²); ``target_std``: each target's std over them (the
    ground-truth error's scale); ``spread``: each target's std over every row, the scale of
    the control-space phase (in ``target_std`` units a wide draw's error would be
    thousands, and would swamp the corpus).
    """

    inputs: torch.Tensor  # (N, D)
    targets: torch.Tensor  # (N, C)
    known: torch.Tensor  # (N,) bool
    natural: torch.Tensor  # (N,) bool
    joints: torch.Tensor  # (N, J + 1, 3): the joints and the COG the inputs hold
    target_std: torch.Tensor  # (C,)
    spread: torch.Tensor  # (C,)
    joint_scale: float

    @classmethod
    def build(
        cls, forward: PlacedRigForward, X, Y, drawn_X, drawn_Y, n_wide: int
    ) -> JointSpaceData:
        inputs = np.concatenate([X, drawn_X])
        targets = np.concatenate([Y, drawn_Y])
        known = np.zeros(len(inputs), dtype=bool)
        known[: len(X)] = True
        natural = np.ones(len(inputs), dtype=bool)
        natural[len(inputs) - n_wide :] = False
        _, std = column_scale(Y)
        _, spread = column_scale(targets)
        return cls.from_rows(
            forward,
            inputs,
            targets,
            known,
            natural,
            target_std=float32_tensor(std),
            spread=float32_tensor(spread),
            scale_rows=slice(None, len(X)),
        )

    @classmethod
    def from_rows(
        cls,
        forward: PlacedRigForward,
        inputs: np.ndarray,
        targets: np.ndarray,
        known: np.ndarray,
        natural: np.ndarray,
        *,
        target_std: torch.Tensor,
        spread: torch.Tensor,
        scale_rows: slice,
    ) -> JointSpaceData:
        """The rows as tensors, with the joints and COG ``forward`` puts at each input row;
        ``joint_scale`` is the mean joint-coordinate variance over ``scale_rows``."""
        joints, cog = forward.input_pose(inputs)
        points = np.concatenate([joints, cog[:, None, :]], axis=1)
        rows = points[scale_rows]
        scale = float(rows.reshape(len(rows), -1).var(axis=0).mean())
        return cls(
            inputs=float32_tensor(inputs),
            targets=float32_tensor(targets),
            known=torch.from_numpy(known),
            natural=torch.from_numpy(natural),
            joints=float32_tensor(points),
            target_std=target_std,
            spread=spread,
            joint_scale=max(scale, 1e-12),
        )

    def control_cost(self, predicted: torch.Tensor, rows: torch.Tensor, scale=None) -> torch.Tensor:
        """Mean squared target error of ``rows`` in ``scale`` (default ``target_std``) units."""
        scale = self.target_std if scale is None else scale
        return ((predicted - self.targets[rows]) / scale).square().mean()


def joint_space_cost(network, forward: PlacedRigForward, data: JointSpaceData, rows, on=None):
    """``(joint, control)`` costs of one minibatch: the joint term (every row, through the
    rig, in ``joint_scale`` units) and the control term on the rows of the mask ``on``
    (default ``data.known``; zero if the minibatch has none)."""
    predicted = network(data.inputs[rows])
    posed = forward(predicted)
    points = torch.cat([posed.joints, posed.cog[:, None, :]], dim=1)
    joint = (points - data.joints[rows]).square().mean() / data.joint_scale
    known = (data.known if on is None else on)[rows]
    if not bool(known.any()):
        return joint, torch.zeros(())
    return joint, data.control_cost(predicted[known], rows[known])
