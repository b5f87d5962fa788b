"""A learned forward stand-in for a rig torch cannot differentiate (issue #39).

A Blender rig is a black box evaluated by worker processes: no gradients, about 130 poses/s
on two workers (``benchmarks/results/distributed.json``). Training an inverse through the
rig (:mod:`rigmap.regression.joint_space_network`), an autodiff Jacobian and tuning on a
clip all need a rig torch can differentiate. The stand-in is a network fitted on poses the
real rig made — used controls to COG-relative joints, the COG and its rotation — behind the
:class:`~rigmap.rigs.base.Rig` protocol with ``differentiable = True``, so code written for
the built-in torch rigs runs on it unchanged. Errors rigmap reports stay measured on the real
rig; the stand-in only guesses and gives gradients. After EA SEED's rig inversion (Marquis
Bolduc & Phan 2022), which trains an inverse through a frozen learned rig; written here.

It covers the poses the joint-space training draws: the root channels (placement) at zero,
every other used control inside its soft range. Placement is exact and analytic
(:class:`~rigmap.regression.rig_forward.PlacedRigForward`), so nothing is learned for it; a
pose with a root channel away from zero is refused. Saved as arrays + JSON with probe poses
of the real rig: a rig that poses them differently today is a changed rig, and refused.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from rigmap.error_measures import joint_error, joint_rms
from rigmap.regression import model_io
from rigmap.regression.errors import ModelFileError, ModelMismatchError, RegressionInputError
from rigmap.regression.joint_space_network import linear_layers, one_cycle
from rigmap.regression.network import _adam, _deterministic_algorithms
from rigmap.regression.normalisation import column_scale
from rigmap.rigs.base import Pose, Rig, RigInputError
from rigmap.stopwatch import Stopwatch
from rigmap.torch_threads import torch_threads

KIND = "stand_in"
FORMAT = "rigmap.stand_in/1"
#: probe poses kept with the stand-in to recognise its rig, and how far the rig may pose them
#: from what it did at fit time (cm; ours: Blender computes in float32, ~1e-5 cm at 100 cm)
PROBES = 4
PROBE_TOLERANCE_CM = 0.01
_ROTATION_COLUMNS = 6  # the COG rotation's first two columns (a continuous parametrisation)


@dataclass(frozen=True)
class StandInSettings:
    """How the stand-in network is shaped and trained (all ours, issue #39).

    ``hidden`` x ``layers`` SiLU units (smooth, so its Jacobian is too: a ReLU network's
    is piecewise constant); Adam at ``learning_rate`` cosine-decayed to ``final_fraction``
    of it over ``epochs`` of ``batch_size`` rows; ``holdout``: the fraction of the rows kept
    out of training to report its error on; ``threads``: torch threads while training.
    """

    hidden: int = 512
    layers: int = 3
    epochs: int = 60
    batch_size: int = 256
    learning_rate: float = 1e-3
    final_fraction: float = 0.01
    holdout: float = 0.1
    seed: int = 0
    threads: int | None = 1

    def check(self) -> None:
        for name in ("hidden", "layers", "epochs", "batch_size"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise RegressionInputError(
                    f"stand-in setting {name} must be a whole number >= 1, got {value!r}"
                )
        for name, low, high in (("learning_rate", 0, math.inf), ("final_fraction", 0, 1)):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and low < value <= high):
                raise RegressionInputError(
                    f"stand-in setting {name} must be in ({low}, {high}], got {value!r}"
                )
        if not 0 < float(self.holdout) < 1:
            raise RegressionInputError(
                f"stand-in setting holdout must be a fraction in (0, 1), got {self.holdout!r}"
            )


class StandInNetwork(torch.nn.Module):
    """Standardised controls -> SiLU layers -> joints, COG and rotation columns.

    Every number that maps raw controls to raw outputs is a buffer, so the state dict is
    the whole network. It computes in its input's dtype (float32 weights cast up for a
    float64 input), so a float64 Jacobian of it is its own, not float32 rounding.
    """

    def __init__(self, n_inputs: int, hidden: int, layers: int, n_outputs: int, generator=None):
        super().__init__()
        self.layers = linear_layers([n_inputs] + [hidden] * layers + [n_outputs], generator)
        for name, width in (("x_mean", n_inputs), ("x_std", n_inputs)):
            self.register_buffer(name, torch.zeros(width, dtype=torch.float64))
        for name in ("y_mean", "y_scale"):
            self.register_buffer(name, torch.zeros(n_outputs, dtype=torch.float64))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        dtype = x.dtype
        z = (x - self.x_mean.to(dtype)) / self.x_std.to(dtype)
        for layer in self.layers[:-1]:
            z = torch.nn.functional.silu(_linear(layer, z))
        return self.y_mean.to(dtype) + self.y_scale.to(dtype) * _linear(self.layers[-1], z)


def _linear(layer: torch.nn.Linear, z: torch.Tensor) -> torch.Tensor:
    if layer.weight.dtype == z.dtype:
        return layer(z)
    return torch.nn.functional.linear(z, layer.weight.to(z.dtype), layer.bias.to(z.dtype))


@dataclass
class StandInFit:
    """What a fit measured: held-out joint RMS (cm) per joint and over all, rows, seconds."""

    heldout_rms_cm: float
    heldout_rms_per_joint_cm: dict[str, float]
    heldout_cog_rms_cm: float
    train_rows: int
    heldout_rows: int
    seconds: float
    history: list[float] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class StandInRig(Rig):
    """The real rig's controls and joints, posed by a :class:`StandInNetwork`.

    ``root_columns``: the used controls that place the whole character (zero in every
    pose the stand-in knows); the network reads the other used controls.
    """

    differentiable = True

    def __init__(
        self,
        rig: Rig,
        network: StandInNetwork,
        root_columns: Sequence[int],
        *,
        fit: StandInFit | None = None,
        probes: tuple[np.ndarray, np.ndarray] | None = None,
        settings: StandInSettings | None = None,
    ):
        self.name = rig.name
        self.controls = rig.controls
        self.joint_names = list(rig.joint_names)
        self.parents = rig.parents
        self.length_unit = rig.length_unit
        self.description = f"learned stand-in of rig {rig.name!r}"
        self.network = network.eval()
        for parameter in self.network.parameters():
            parameter.requires_grad_(False)
        used = len(rig.controls.used_indices)
        self.root_columns = [int(c) for c in root_columns]
        self.input_columns = [c for c in range(used) if c not in set(self.root_columns)]
        self._used = torch.as_tensor(rig.controls.used_indices)
        self._inputs = torch.as_tensor(self.input_columns, dtype=torch.long)
        self._roots = torch.as_tensor(self.root_columns, dtype=torch.long)
        self.fit = fit
        self.probes = probes
        self.settings = settings or StandInSettings()

    def _pose(self, Y) -> Pose:
        if isinstance(Y, torch.Tensor):
            return self._pose_tensor(Y)
        with torch.no_grad():
            pose = self._pose_tensor(torch.from_numpy(np.asarray(Y, dtype=np.float64)))
        return Pose(*(p.numpy() for p in pose))

    def _pose_tensor(self, Y: torch.Tensor) -> Pose:
        used = Y.index_select(1, self._used)
        if len(self.root_columns) and bool(used.index_select(1, self._roots).ne(0).any()):
            raise RigInputError(
                f"{self.description}: it poses the character with its root channels at zero "
                f"(controls {[self.used_controls[c] for c in self.root_columns]}); place the "
                "pose with rigmap.regression.rig_forward.PlacedRigForward"
            )
        out = self.network(used.index_select(1, self._inputs))
        n, width = len(out), 3 * self.n_joints
        positions = out[:, :width].reshape(n, self.n_joints, 3)
        cog = out[:, width : width + 3]
        rotation = rotation_from_columns(out[:, width + 3 :])
        return Pose(positions, cog, rotation)


def rotation_from_columns(columns: torch.Tensor) -> torch.Tensor:
    """``(N, 3, 3)`` rotations from two predicted columns ``(N, 6)``, made orthonormal
    (Gram-Schmidt; Zhou et al. 2019's continuous 6-D parametrisation)."""
    first = torch.nn.functional.normalize(columns[:, :3], dim=1)
    second = columns[:, 3:] - (first * columns[:, 3:]).sum(1, keepdim=True) * first
    second = torch.nn.functional.normalize(second, dim=1)
    third = torch.linalg.cross(first, second, dim=1)
    return torch.stack([first, second, third], dim=2)


def pose_outputs(pose: Pose) -> np.ndarray:
    """A real pose as the stand-in's output row: joints, COG, two rotation columns."""
    positions = np.asarray(pose.positions, dtype=np.float64)
    n = len(positions)
    rotation = np.asarray(pose.cog_rotation, dtype=np.float64)
    columns = np.concatenate([rotation[:, :, 0], rotation[:, :, 1]], axis=1)
    return np.concatenate([positions.reshape(n, -1), np.asarray(pose.cog), columns], axis=1)


def fit_stand_in(
    rig: Rig,
    controls: np.ndarray,
    pose: Pose,
    root_columns: Sequence[int] = (),
    settings: StandInSettings | None = None,
    *,
    progress: bool = True,
) -> StandInRig:
    """A stand-in of ``rig`` fitted on used ``controls`` ``(N, C_used)`` and the ``pose`` the
    real rig made of them (root channels at zero); its held-out error in ``.fit``."""
    settings = settings or StandInSettings()
    settings.check()
    controls = np.asarray(controls, dtype=np.float64)
    used = rig.controls.used_indices
    if controls.ndim != 2 or controls.shape[1] != len(used) or len(controls) < 10:
        raise RegressionInputError(
            f"stand-in of rig {rig.name!r}: expected used controls of shape (N >= 10, "
            f"{len(used)}), got {controls.shape}"
        )
    if root_columns and np.any(controls[:, list(root_columns)] != 0):
        raise RegressionInputError(
            f"stand-in of rig {rig.name!r}: the root channels must be zero in every row"
        )
    outputs = pose_outputs(pose)
    if len(outputs) != len(controls) or not np.isfinite(outputs).all():
        raise RegressionInputError(
            f"stand-in of rig {rig.name!r}: {len(outputs)} finite poses needed for "
            f"{len(controls)} control rows"
        )
    watch = Stopwatch().start()
    generator = torch.Generator().manual_seed(int(settings.seed))
    order = torch.randperm(len(controls), generator=generator).numpy()
    n_heldout = max(1, round(float(settings.holdout) * len(controls)))
    heldout, train = order[:n_heldout], order[n_heldout:]
    inputs = np.delete(controls, list(root_columns), axis=1)
    network = _new_network(inputs[train], outputs[train], rig.n_joints, settings, generator)
    with torch_threads(settings.threads), _deterministic_algorithms():
        history = _train(network, inputs[train], outputs[train], settings, generator, progress)
    stand_in = StandInRig(rig, network, root_columns, settings=settings)
    with torch.no_grad():
        guess = network(torch.from_numpy(inputs[heldout])).numpy()
    width = 3 * rig.n_joints
    error = (guess[:, :width] - outputs[heldout, :width]).reshape(n_heldout, -1, 3)
    per_joint = np.sqrt((error**2).sum(axis=2).mean(axis=0))
    cog_error = guess[:, width : width + 3] - outputs[heldout, width : width + 3]
    stand_in.fit = StandInFit(
        heldout_rms_cm=joint_rms(joint_error(guess[:, :width], outputs[heldout, :width]).mean),
        heldout_rms_per_joint_cm=dict(zip(rig.joint_names, map(float, per_joint), strict=True)),
        heldout_cog_rms_cm=float(np.sqrt((cog_error**2).sum(axis=1).mean())),
        train_rows=len(train),
        heldout_rows=n_heldout,
        seconds=watch.stop(),
        history=history,
    )
    stand_in.probes = _probe(rig, controls, root_columns)
    return stand_in


def _new_network(inputs, outputs, n_joints: int, settings: StandInSettings, generator):
    network = StandInNetwork(
        inputs.shape[1], settings.hidden, settings.layers, outputs.shape[1], generator
    )
    x_mean, x_std = column_scale(inputs)
    width = 3 * n_joints + 3
    y_mean = outputs.mean(axis=0)
    y_scale = np.ones(outputs.shape[1])
    # one length scale for every joint and the COG, so the cost weighs centimetres alike
    y_scale[:width] = max(float(outputs[:, :width].std(axis=0).mean()), 1e-6)
    y_mean[width:] = 0.0  # rotation columns are unit vectors already
    with torch.no_grad():
        network.x_mean.copy_(torch.from_numpy(x_mean))
        network.x_std.copy_(torch.from_numpy(x_std))
        network.y_mean.copy_(torch.from_numpy(y_mean))
        network.y_scale.copy_(torch.from_numpy(y_scale))
    return network


def _train(network, inputs, outputs, settings: StandInSettings, generator, progress) -> list[float]:
    """Adam on the squared error in the network's output units; the mean cost per epoch."""
    x = torch.from_numpy(inputs.astype(np.float32))
    y = torch.from_numpy(outputs.astype(np.float32))
    scale = network.y_scale.to(torch.float32)
    n, batch = len(x), int(settings.batch_size)
    steps = int(settings.epochs) * math.ceil(n / batch)
    optimizer = _adam(list(network.parameters()), float(settings.learning_rate))
    decay = torch.optim.lr_scheduler.LambdaLR(
        optimizer, one_cycle(steps, 0, float(settings.final_fraction))
    )
    history = []
    for _ in tqdm(range(int(settings.epochs)), desc="stand-in", disable=not progress, leave=False):
        order = torch.randperm(n, generator=generator)
        total = 0.0
        for start in range(0, n, batch):
            rows = order[start : start + batch]
            cost = ((network(x[rows]) - y[rows]) / scale).square().mean()
            optimizer.zero_grad(set_to_none=True)
            cost.backward()
            optimizer.step()
            decay.step()
            total += float(cost.detach()) * len(rows)
        history.append(total / n)
        if not math.isfinite(history[-1]):
            raise RegressionInputError(
                f"stand-in training diverged (cost {history[-1]} in epoch {len(history)}); "
                "lower its learning_rate"
            )
    return history


def _probe(rig: Rig, controls: np.ndarray, root_columns: Sequence[int]):
    """``PROBES`` control rows spread over the fit's rows and the real rig's joints there."""
    picks = np.linspace(0, len(controls) - 1, PROBES).round().astype(int)
    probe = controls[picks].copy()
    probe[:, list(root_columns)] = 0.0
    pose = rig.pose(rig.expand_used(probe))
    return probe, _points(pose)


def _points(pose: Pose) -> np.ndarray:
    positions = np.asarray(pose.positions, dtype=np.float64)
    return np.concatenate([positions, np.asarray(pose.cog, dtype=np.float64)[:, None]], axis=1)


# ---------------------------------------------------------------------- files
def save_stand_in(stand_in: StandInRig, folder: str | os.PathLike) -> Path:
    """``stand_in.npz`` (the network, the probes) and ``stand_in.json`` beside it."""
    if stand_in.probes is None or stand_in.fit is None:
        raise ModelFileError(f"{stand_in.description}: only a fitted stand-in can be saved")
    state = stand_in.network.state_dict()
    arrays = {k: v.detach().numpy().astype(np.float64) for k, v in state.items()}
    arrays["probe_controls"], arrays["probe_points"] = stand_in.probes
    meta = {
        "kind": KIND,
        "format": FORMAT,
        "rig": stand_in.name,
        "control_names": stand_in.control_names,
        "used_controls": stand_in.used_controls,
        "joint_names": stand_in.joint_names,
        "root_columns": stand_in.root_columns,
        "settings": asdict(stand_in.settings),
        "fit": stand_in.fit.to_dict(),
    }
    Path(folder).mkdir(parents=True, exist_ok=True)
    return model_io.write_model_files(folder, KIND, model_io.arrays_to_bytes(arrays), ".npz", meta)


def load_stand_in(folder: str | os.PathLike, rig: Rig) -> StandInRig:
    """The stand-in saved in ``folder``, refused unless ``rig`` is the rig it was fitted on
    (same name, controls and joints, and the probe poses again within 0.01 cm)."""
    meta, payload = model_io.read_model_files(folder, KIND, KIND)
    source = str(Path(folder) / f"{KIND}.json")
    if meta.get("format") != FORMAT:
        raise ModelFileError(f"{source}: format {meta.get('format')!r}, expected {FORMAT!r}")
    try:
        settings = StandInSettings(**meta["settings"])
        fit = StandInFit(**meta["fit"])
        expected = {
            "rig": rig.name,
            "control_names": rig.control_names,
            "used_controls": rig.used_controls,
            "joint_names": list(rig.joint_names),
        }
        root_columns = [int(c) for c in meta["root_columns"]]
        found = {key: meta[key] for key in expected}
    except (KeyError, TypeError, ValueError) as error:
        raise ModelFileError(f"{source}: not a valid stand-in ({error})") from None
    for key, value in expected.items():
        if found[key] != value:
            raise ModelMismatchError(
                f"{source} is a stand-in of rig {meta['rig']!r}, fitted with other {key} than "
                f"rig {rig.name!r} has; fit a stand-in for this rig"
            )
    n_inputs = len(rig.used_controls) - len(root_columns)
    width = 3 * rig.n_joints + 3 + _ROTATION_COLUMNS
    network = StandInNetwork(n_inputs, settings.hidden, settings.layers, width)
    names = [*network.state_dict(), "probe_controls", "probe_points"]
    arrays = model_io.arrays_from_bytes(payload, source, names)
    try:
        network.load_state_dict(
            {k: torch.from_numpy(arrays[k]).to(v.dtype) for k, v in network.state_dict().items()}
        )
    except RuntimeError as error:
        raise ModelFileError(f"{source}: its network does not fit its settings ({error})") from None
    probes = (arrays["probe_controls"], arrays["probe_points"])
    _check_probes(rig, probes, source)
    return StandInRig(rig, network, root_columns, fit=fit, probes=probes, settings=settings)


def _check_probes(rig: Rig, probes: tuple[np.ndarray, np.ndarray], source: str) -> None:
    controls, points = probes
    if controls.shape != (PROBES, len(rig.used_controls)) or points.shape != (
        PROBES,
        rig.n_joints + 1,
        3,
    ):
        raise ModelFileError(f"{source}: its probe poses have the wrong shape")
    now = _points(rig.pose(rig.expand_used(controls)))
    moved = float(np.abs(now - points).max())
    if moved > PROBE_TOLERANCE_CM:
        raise ModelMismatchError(
            f"{source}: rig {rig.name!r} poses the stand-in's probe controls up to {moved:.3g} "
            f"cm away from where it did when the stand-in was fitted (tolerance "
            f"{PROBE_TOLERANCE_CM} cm): the rig changed; fit the stand-in again"
        )
