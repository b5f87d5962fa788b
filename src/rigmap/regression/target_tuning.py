"""Fine-tuning the joint-space network on the very poses being mapped (issue #15, item 2).

What a user maps is joint positions, and the joint-space cost needs nothing
else: no controls are known for them, so the network can be trained further on
the target clip itself before it predicts it. EA SEED's published inversion
code trains its encoder on the capture it inverts the same way; its neutral-pose
term (the rest pose in, the default controls out) is the cheap regulariser that
keeps the controls from drifting where joints do not pin them. On the quadruped
it is not enough (measured: joint error 48 -> 1.4 cm², ground-truth error 3.3 -> 201),
so each target frame is also anchored to the general network's own controls for it:

    ||rig(Phi(x)) - x||² / s_x  [target rows and the rest pose]
      + control_weight * ||(Phi(x) - y0) / s_y||²  [y0: the defaults for the rest pose,
                                                     the untuned network's output for a target]

``s_x`` the mean variance of a joint coordinate over the target rows, ``s_y``
each target's standard deviation in the training corpus (the ground-truth
error's scale). The tuned copy is returned; the fitted model is untouched.
Every setting is ours; with the defaults (160 steps, Adam 1e-3, weight 0.001) the
committed joint-space networks on the extreme test clips went from 4.78 to 0.20 cm²
(quadruped; ground truth 2.85 -> 2.36) and from 9.21 to 0.45 cm² (biped; 5.21 -> 5.91);
80 steps at weight 0.01 stopped at 0.58 and 1.56 — ``benchmarks/target_tuning.py``,
``benchmarks/results/target_tuning_s34.json``.
"""

from __future__ import annotations

import contextlib
import copy
import math
import time
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
import torch

from rigmap.regression.features import default_pose_features
from rigmap.regression.joint_space_network import JointSpaceNetworkRegressor
from rigmap.regression.joint_space_training import JointSpaceData, joint_space_cost
from rigmap.regression.mapping import InverseMapping
from rigmap.regression.network import _adam
from rigmap.regression.rig_forward import PlacedRigForward
from rigmap.torch_threads import torch_threads

#: steps of an evaluation's untimed warm-up call (ours: two pay the first calls' costs)
WARMUP_STEPS = 2


@dataclass(frozen=True)
class TuningSettings:
    """Adam steps over the target rows (``batch_size`` per step), and the control term's weight."""

    steps: int = 160
    batch_size: int = 512
    learning_rate: float = 1e-3
    control_weight: float = 0.001

    def __post_init__(self) -> None:
        if self.steps < 0 or self.batch_size < 1:
            raise ValueError(f"TuningSettings: steps >= 0 and batch_size >= 1, got {self}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"TuningSettings: learning_rate must be > 0, got {self.learning_rate}")
        if not (math.isfinite(self.control_weight) and self.control_weight >= 0):
            raise ValueError(
                f"TuningSettings: control_weight must be >= 0, got {self.control_weight}"
            )


def _tuning_data(forward: PlacedRigForward, mapping: InverseMapping, X_pose) -> JointSpaceData:
    """Row 0: the rest pose with its default controls; then the targets with the untuned
    network's controls for them (the anchors of the control term)."""
    rig, placement = forward.rig, mapping.placement
    rest_row = default_pose_features(rig)
    defaults = rig.controls.defaults[rig.controls.used_indices][None]
    rest_in = placement.inputs(rest_row)
    rest_target = placement.targets(defaults, rest_row)
    targets_in = placement.inputs(X_pose, "target poses to tune on")
    inputs = np.concatenate([rest_in, targets_in])
    network = mapping.regressor.network_
    scale = network.free_std.clamp_min(1e-12)  # the training corpus's target std
    anchors = np.concatenate([rest_target, mapping.regressor.predict(targets_in)])
    known = np.ones(len(inputs), dtype=bool)
    return JointSpaceData.from_rows(
        forward,
        inputs,
        anchors,
        known,
        known,
        target_std=scale.float(),
        spread=scale.float(),
        scale_rows=slice(1, None),
    )


def tune_on_targets(
    mapping: InverseMapping, rig: Any, X_pose: Any, settings: TuningSettings = TuningSettings()
) -> tuple[InverseMapping, dict[str, Any]]:
    """A copy of ``mapping`` trained on the pose rows ``X_pose`` it is about to predict.

    Returns the tuned mapping and what happened (steps, costs, seconds).
    """
    if not isinstance(mapping.regressor, JointSpaceNetworkRegressor):
        raise TypeError(
            f"tuning on the target needs a joint-space network (regressor=nn_joint_space), got "
            f"{type(mapping.regressor).__name__}"
        )
    started = time.perf_counter()
    forward = PlacedRigForward(rig, mapping.placement, who="tuning on the target")
    tuned = copy.deepcopy(mapping.regressor)
    data = _tuning_data(forward, mapping, X_pose)
    network = tuned.network_
    network.train()
    optimizer = _adam(list(network.parameters()), float(settings.learning_rate))
    generator = torch.Generator().manual_seed(int(tuned.seed))
    n_targets, costs = len(data.inputs) - 1, []
    with torch_threads(tuned.threads):
        for _ in range(int(settings.steps)):
            pick = torch.randperm(n_targets, generator=generator)[: settings.batch_size] + 1
            rows = torch.cat([torch.zeros(1, dtype=torch.long), pick])
            joint, control = joint_space_cost(network, forward, data, rows)
            cost = joint + float(settings.control_weight) * control
            optimizer.zero_grad(set_to_none=True)
            cost.backward()
            optimizer.step()
            costs.append({"joint": float(joint.detach()), "control": float(control.detach())})
    network.eval()
    report = {
        "settings": asdict(settings),
        "rows": n_targets,
        "first": costs[0] if costs else None,
        "last": costs[-1] if costs else None,
        "seconds": time.perf_counter() - started,
    }
    return InverseMapping(tuned, mapping.placement), report


class TunedOnTarget:
    """An inverse mapping that tunes a copy of itself on every batch it predicts, then predicts.

    The evaluation's method runner times ``predict``, so the tuning is inside the clock.
    Its rig evaluations (``steps`` batches through the torch rig) are not in the runner's
    rig-evaluation count; ``reports`` keeps what each call did.
    """

    def __init__(self, mapping: InverseMapping, rig: Any, settings: TuningSettings):
        self.mapping = mapping
        self.rig = rig
        self.settings = settings
        self.reports: list[dict[str, Any]] = []

    @contextlib.contextmanager
    def warming_up(self):
        """Calls inside tune for at most :data:`WARMUP_STEPS` steps (an evaluation's untimed
        warm-up: the tuning starts from the same copy and seed every call, so what the
        timed call returns does not depend on it)."""
        settings = self.settings
        self.settings = replace(settings, steps=min(settings.steps, WARMUP_STEPS))
        try:
            yield self
        finally:
            self.settings = settings

    def predict(self, X_pose: Any) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X_pose, dtype=np.float64))
        tuned, report = tune_on_targets(self.mapping, self.rig, X, self.settings)
        self.reports.append(report)
        predicted = tuned.predict(X)
        return predicted[0] if np.ndim(X_pose) == 1 else predicted
