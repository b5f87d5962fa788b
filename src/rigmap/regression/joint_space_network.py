"""A network inverse mapping trained through the rig, with its loss in joint space.

The paper's network (§5.3, :mod:`rigmap.regression.network`) regresses controls:
its loss is ``||y - Phi(x)||²``. Far from the corpus that loss has nothing to
say (no controls are known there) and, where several control vectors give one
pose, it averages them. EA SEED's rig inversion (Marquis Bolduc & Phan 2022)
trains the inverse with its loss where the user looks, on the pose the rig
makes of the predicted controls; rigmap's built-in rigs are differentiable
torch programs, so that loss is exact here. The cost per row is

    ||rig(Phi(x)) - x||² / s_x + w ||(Phi(x) - y) / s_y||² [on rows with natural controls]

in the frame the placement's inputs use (:mod:`rigmap.regression.rig_forward`:
COG-relative joints in the COG's heading frame, plus the COG itself as one
more point, so the root channels put the character where the target stands),
``s_x`` the mean variance of a joint coordinate in the given rows (so the term
is scale-free), ``s_y`` each target's standard deviation in them (the ground-
truth error's scale). The control term ``w`` keeps the controls natural: many
control vectors make a pose, and the animators' are the ones to give. It covers
the given rows and (``control_rows="natural"``) the draws around the corpus,
whose controls are near the animators': on the quadruped's extreme test clips
that kept the ground-truth error at 3.3 (control-space network 4.4) where the
corpus rows alone let it grow to 9 (measured, quick budget).

What it is trained on (``fit``): the rows it is given (corpus frames, the rest
pose, a sampler's samples), which carry controls, plus draws of its own that
carry only poses — ``n_gaussian`` around the corpus (PCA + unit Gaussian,
Algorithm 2, clamped to the soft ranges), ``n_local`` that move every control
of a corpus frame or a PCA draw by its own noise, and ``n_wide`` uniform over
the soft ranges — so the mapping has seen poses far outside the corpus. The
draws' root channels are zero: the placement removes them.

Outputs: every target column that is a control is squashed into its soft
range, ``lower + (upper - lower) * sigmoid(z)``, so no prediction leaves it;
the root channels' placement offsets (cm, radians) are unbounded,
``mean + std * z``. Training runs in two phases: ``pretrain_epochs`` in control
space over every row (the draws' controls are known; no rig call, cheap) to
start near the paper's network, then ``epochs`` through the rig. Every count
and weight here is ours (the paper has no such network); see
``conf/regressor/nn_joint_space.yaml``.
"""

from __future__ import annotations

import hashlib
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from rigmap.regression import model_io
from rigmap.regression.base import Regressor
from rigmap.regression.errors import ModelFileError
from rigmap.regression.fingerprint import ModelFingerprint
from rigmap.regression.joint_space_training import (
    JointSpaceData,
    draw_training_controls,
    joint_space_cost,
    pose_training_draws,
)
from rigmap.regression.network import (
    TrainingDivergedError,
    _adam,
    _deterministic_algorithms,
)
from rigmap.regression.normalisation import column_scale
from rigmap.regression.rig_forward import PlacedRigForward
from rigmap.regression.validation import check_training_data
from rigmap.stopwatch import Stopwatch
from rigmap.torch_threads import torch_threads

_PREDICT_CHUNK = 65_536
#: rows the joint-space phase's control term covers: those given with controls, or those and
#: the draws around the corpus (whose controls are near the animators')
CONTROL_ROWS = ("known", "natural")
_BUFFERS = ("x_mean", "x_std", "lower", "span", "free_mean", "free_std", "bounded")
#: the last ``learned_inputs`` answer: an evaluation asks it once per method of one model,
#: and the draws take seconds to pose (module-level so a deep copy of the model, as tuning
#: makes, does not copy it)
_LAST_LEARNED: dict[str, Any] = {}
_EDGE = 1e-4  # the fraction of a soft range the initial bias stays inside of its ends


def linear_layers(sizes: Sequence[int], generator=None) -> torch.nn.ModuleList:
    """Linear layers between consecutive ``sizes``, drawn from ``generator`` as torch draws
    them by default (uniform within ``1 / sqrt(fan_in)``), so a seeded fit repeats."""
    layers = torch.nn.ModuleList(torch.nn.Linear(a, b) for a, b in itertools.pairwise(sizes))
    if generator is not None:
        with torch.no_grad():
            for layer in layers:
                bound = 1.0 / math.sqrt(layer.in_features)
                layer.weight.uniform_(-bound, bound, generator=generator)
                layer.bias.uniform_(-bound, bound, generator=generator)
    return layers


def one_cycle(steps: int, warm: int, final: float):
    """The learning-rate factor at each step: a linear warm-up from a tenth over ``warm``
    steps, then cosine down to ``final`` at ``steps`` (no warm-up: plain cosine)."""
    rest = max(steps - warm, 1)

    def factor(step: int) -> float:
        if step < warm:
            return 0.1 + 0.9 * step / warm
        done = min((step - warm) / rest, 1.0)
        return final + (1 - final) * 0.5 * (1 + math.cos(math.pi * done))

    return factor


class SquashedNetwork(torch.nn.Module):
    """Standardised inputs -> ReLU layers -> targets squashed into their ranges.

    Every number it needs to map raw inputs to raw targets is a buffer, so its
    state dict is the whole model. The buffers are float64, so the soft ranges are
    exact where :meth:`JointSpaceNetworkRegressor.predict` clips float32 round-off.
    """

    def __init__(self, n_inputs: int, hidden: int, layers: int, n_outputs: int, generator=None):
        super().__init__()
        self.layers = linear_layers([n_inputs] + [hidden] * layers + [n_outputs], generator)
        for name, width in (("x_mean", n_inputs), ("x_std", n_inputs)):
            self.register_buffer(name, torch.zeros(width, dtype=torch.float64))
        for name in ("lower", "span", "free_mean", "free_std", "bounded"):
            self.register_buffer(name, torch.zeros(n_outputs, dtype=torch.float64))

    def set_scales(self, x_mean, x_std, lower, upper, free_mean, free_std, bounded) -> None:
        values = {
            "x_mean": x_mean,
            "x_std": x_std,
            "lower": lower,
            "span": np.asarray(upper) - np.asarray(lower),
            "free_mean": free_mean,
            "free_std": free_std,
            "bounded": np.asarray(bounded, dtype=np.float64),
        }
        for name, value in values.items():
            getattr(self, name).copy_(torch.as_tensor(np.asarray(value), dtype=torch.float64))

    def start_at(self, targets: np.ndarray) -> None:
        """Last bias at the targets' mean (inside the squash), last weights small."""
        mean = torch.as_tensor(targets.mean(axis=0), dtype=torch.float64)
        fraction = ((mean - self.lower) / self.span.clamp_min(1e-12)).clamp(_EDGE, 1 - _EDGE)
        bias = torch.where(self.bounded > 0, torch.logit(fraction), torch.zeros_like(mean))
        with torch.no_grad():
            self.layers[-1].bias.copy_(bias.to(self.layers[-1].bias.dtype))
            self.layers[-1].weight.mul_(0.1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        buffer = {name: getattr(self, name).to(x.dtype) for name in _BUFFERS}
        z = (x - buffer["x_mean"]) / buffer["x_std"]
        for layer in self.layers[:-1]:
            z = layer(z).relu()
        z = self.layers[-1](z)
        squashed = buffer["lower"] + buffer["span"] * torch.sigmoid(z)
        free = buffer["free_mean"] + buffer["free_std"] * z
        return torch.where(buffer["bounded"] > 0, squashed, free)

    def clip(self, targets: np.ndarray) -> np.ndarray:
        """``targets`` with the squashed columns clipped into their exact (float64) ranges:
        the squash keeps them inside up to float32 round-off at the ends."""
        lower, upper = self.lower.numpy(), (self.lower + self.span).numpy()
        bounded = self.bounded.numpy() > 0
        return np.where(bounded, np.clip(targets, lower, upper), targets)


@dataclass(eq=False, repr=False)
class JointSpaceNetworkRegressor(Regressor):
    """Pose inputs ``(N, D)`` -> placement targets ``(N, C)``, trained through the rig.

    Parameters (all ours; the module docstring says why each exists):

    - ``hidden``, ``layers``: ReLU layers of ``hidden`` units.
    - ``n_gaussian``, ``gaussian_scale``: draws around the corpus (PCA, whitened).
    - ``n_local``, ``local_scale``: draws that move each control of a corpus frame or a
      PCA draw by its own noise (``local_scale`` corpus stds; issue #15's ears at 4 stds).
    - ``n_wide``: draws uniform over the soft ranges.
    - ``pretrain_epochs``, ``pretrain_batch``: control-space phase.
    - ``epochs``, ``batch_size``: joint-space phase (each step one rig evaluation
      of ``batch_size`` rows, forward and backward).
    - ``control_weight``: ``w``, the control term on rows with known controls.
    - ``control_rows``: ``known`` (the given rows) or ``natural`` (those and the draws
      around the corpus) carry the control term in the joint-space phase.
    - ``learning_rate``: Adam's, decayed to a tenth over the control-space phase (cosine).
    - ``joint_learning_rate``, ``warmup``, ``final_fraction``: the joint-space phase's peak
      rate (default ``learning_rate``), reached by a linear warm-up from a tenth of it over
      the first ``warmup`` fraction of its steps, then cosine-decayed to ``final_fraction``
      of it (``warmup=0, final_fraction=0.1``: plain cosine to a tenth; a warm-up and a
      small final fraction: a one-cycle schedule).
    - ``compiled_rig_min_steps``: a joint-space phase of at least this many steps runs the
      rig through its inductor-compiled pass (:mod:`rigmap.rigs.engine.compiled`), whose
      compile (70-85 s on a cold cache, about 10 s warm) only a long loop repays; ``None``
      never compiles. Rigs without a compiled pass (the face and mesh rigs) run eagerly.
    - ``seed``, ``progress``, ``threads``: as the paper's network.
    """

    name = "nn_joint_space"

    hidden: int = 512
    layers: int = 2
    n_gaussian: int = 3000
    gaussian_scale: float = 1.0
    n_wide: int = 3000
    n_local: int = 0
    local_scale: float = 2.0
    pretrain_epochs: int = 20
    pretrain_batch: int = 128
    epochs: int = 2
    batch_size: int = 512
    control_weight: float = 0.05
    control_rows: str = "natural"
    learning_rate: float = 1e-3
    joint_learning_rate: float | None = None
    warmup: float = 0.0
    final_fraction: float = 0.1
    compiled_rig_min_steps: int | None = None
    seed: int = 0
    progress: bool = True
    threads: int | None = 1

    def _repr_fields(self) -> dict[str, Any]:
        draws = f"{self.n_gaussian}+{self.n_local}+{self.n_wide}"
        epochs = f"{self.pretrain_epochs}+{self.epochs}"
        return {"hidden": self.hidden, "layers": self.layers, "draws": draws, "epochs": epochs}

    def _check_params(self) -> None:
        for name in ("hidden", "layers", "pretrain_batch", "batch_size"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{type(self).__name__}: {name} must be >= 1")
        for name in ("n_gaussian", "n_local", "n_wide", "pretrain_epochs", "epochs"):
            if int(getattr(self, name)) < 0:
                raise ValueError(f"{type(self).__name__}: {name} must be >= 0")
        for name in ("gaussian_scale", "local_scale", "control_weight"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{type(self).__name__}: {name} must be >= 0, got {value}")
        for name in ("learning_rate", "joint_rate"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{type(self).__name__}: {name} must be > 0, got {value}")
        for name in ("warmup", "final_fraction"):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and 0 <= value <= 1):
                raise ValueError(f"{type(self).__name__}: {name} must be in [0, 1], got {value}")
        steps = self.compiled_rig_min_steps
        counts = isinstance(steps, int) and not isinstance(steps, bool)
        if steps is not None and not (counts and steps >= 1):
            raise ValueError(
                f"{type(self).__name__}: compiled_rig_min_steps must be a step count >= 1 "
                f"or null, got {steps!r}"
            )
        if self.control_rows not in CONTROL_ROWS:
            raise ValueError(
                f"{type(self).__name__}: control_rows must be one of {CONTROL_ROWS}, "
                f"got {self.control_rows!r}"
            )

    # ------------------------------------------------------------------ fit
    def rig_fit_options(self, *, rig: Any, placement: Any) -> dict[str, Any]:
        return {"rig": rig, "placement": placement}

    def describe_plan(self, rows: int) -> str:
        return (
            f"training {self!r} through the rig on {rows} rows with controls + "
            f"{self.n_draws} drawn poses"
        )

    def fit(
        self,
        X: Any,
        Y: Any,
        *,
        rig: Any = None,
        placement: Any = None,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> JointSpaceNetworkRegressor:
        """Train on ``(X, Y)`` (placement inputs and targets) and draws posed by ``rig``."""
        self._check_params()
        if rig is None or placement is None:
            raise ValueError(
                f"{type(self).__name__}.fit needs the rig and its placement (rig=, placement=); "
                "the fit stage passes them through Regressor.rig_fit_options"
            )
        X, Y = check_training_data(X, Y, type(self).__name__)
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], Y.shape[1], rig_name, control_names)
        setup = Stopwatch().start()
        drawn_X, drawn_Y = self._draw(rig, placement, Y)
        self.draws_summary_ = draws_summary(drawn_X)
        rows = len(X) + len(drawn_X)
        forward = PlacedRigForward(
            rig,
            placement,
            who=f"regressor {self.name!r}",
            compiled_rows=int(self.batch_size) if self._compiles(rig, rows) else None,
        )
        data = JointSpaceData.build(forward, X, Y, drawn_X, drawn_Y, int(self.n_wide))
        generator = torch.Generator().manual_seed(int(self.seed))
        self.network_ = self._new_network(rig, placement, data, generator)
        self.seconds_ = {"draws_and_setup": setup.stop()}
        with torch_threads(self.threads), _deterministic_algorithms():
            with Stopwatch() as control_space:
                pretrain = self._pretrain(data, generator)
            with Stopwatch() as joint_space:
                joint_space_history = self._train_joint_space(forward, data, generator)
        self.seconds_.update(control_space=control_space.elapsed, joint_space=joint_space.elapsed)
        self.history_ = {"pretrain": pretrain, "joint_space": joint_space_history}
        self.network_.eval()
        return self

    def _compiles(self, rig, rows: int) -> bool:
        """Whether the joint-space phase over ``rows`` rows runs ``rig`` compiled."""
        least = self.compiled_rig_min_steps
        if least is None or not hasattr(rig, "compiled_pose"):
            return False
        return int(self.epochs) * math.ceil(rows / int(self.batch_size)) >= int(least)

    def _draw(self, rig, placement, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The fit's own posed draws around the targets ``Y``, from the model's seed."""
        controls = draw_training_controls(
            rig,
            placement,
            Y,
            int(self.n_gaussian),
            float(self.gaussian_scale),
            int(self.n_wide),
            np.random.default_rng(int(self.seed)),
            n_local=int(self.n_local),
            local_scale=float(self.local_scale),
        )
        return pose_training_draws(rig, placement, controls)

    def learned_inputs(self, X: Any, Y: Any, *, rig: Any, placement: Any) -> np.ndarray:
        """The inputs of every row the network was trained on: the given rows ``(X, Y)``
        (the fit's placement inputs and targets) and its own draws.

        The draws are made again from the seed instead of being saved (54 000 poses would
        triple the model file), and checked against the fit's summary of them, so a
        confidence measured against them is measured against what the fit saw. The check
        has a tolerance: another CPU code path poses them again a few ulps away (issue #36:
        a bit-exact digest refused, on a second machine, models pulled from the remote).
        """
        if not self.is_fitted():
            raise RuntimeError(f"{type(self).__name__} is not fitted: call fit(X, Y) first")
        if getattr(self, "draws_summary_", None) is None:
            raise ModelFileError(
                f"{type(self).__name__}: the model file has no summary of its draws (it "
                "predates them being checked); refit it"
            )
        X, Y = check_training_data(X, Y, type(self).__name__)
        key = (_digest(X), _digest(Y), repr(self.draws_summary_))
        if _LAST_LEARNED.get("key") == key:
            return _LAST_LEARNED["inputs"]
        drawn_X, _ = self._draw(rig, placement, Y)
        if not same_draws(self.draws_summary_, drawn_X):
            raise ModelFileError(
                f"{type(self).__name__}: the draws made again from seed {self.seed} differ "
                "from the fit's: the rows given are not the ones it was fitted on"
            )
        learned = np.concatenate([X, drawn_X])
        learned.setflags(write=False)
        _LAST_LEARNED.update(key=key, inputs=learned)
        return learned

    def _new_network(self, rig, placement, data: JointSpaceData, generator) -> SquashedNetwork:
        used = rig.controls.used_indices
        lower, upper = rig.controls.lower[used].copy(), rig.controls.upper[used].copy()
        bounded = np.ones(len(used), dtype=bool)
        bounded[[c.index for c in placement.channels]] = False
        x_mean, x_std = column_scale(data.inputs.numpy().astype(np.float64))
        free_mean, free_std = column_scale(data.targets.numpy()[data.known].astype(np.float64))
        network = SquashedNetwork(
            data.inputs.shape[1], int(self.hidden), int(self.layers), len(used), generator
        )
        network.set_scales(x_mean, x_std, lower, upper, free_mean, free_std, bounded)
        network.start_at(data.targets.numpy()[data.known].astype(np.float64))
        return network

    @property
    def n_draws(self) -> int:
        """Poses the fit draws of its own (around the corpus, per control, wide)."""
        return int(self.n_gaussian) + int(self.n_local) + int(self.n_wide)

    @property
    def joint_rate(self) -> float:
        """The joint-space phase's peak learning rate."""
        rate = self.joint_learning_rate
        return float(self.learning_rate if rate is None else rate)

    def _joint_schedule(self, steps: int):
        """Adam at ``joint_rate``: a linear warm-up from a tenth, then cosine down to
        ``final_fraction`` of it."""
        optimizer = _adam(list(self.network_.parameters()), self.joint_rate)
        factor = one_cycle(steps, round(float(self.warmup) * steps), float(self.final_fraction))
        return optimizer, torch.optim.lr_scheduler.LambdaLR(optimizer, factor)

    def _schedule(self, steps: int):
        optimizer = _adam(list(self.network_.parameters()), float(self.learning_rate))
        decay = torch.optim.lr_scheduler.CosineAnnealingLR(
            optimizer, max(steps, 1), eta_min=float(self.learning_rate) / 10
        )
        return optimizer, decay

    def _pretrain(self, data: JointSpaceData, generator) -> list[float]:
        """Control-space cost over the natural rows (no wide draws): no rig evaluation."""
        natural = torch.nonzero(data.natural).flatten()
        n, batch = len(natural), int(self.pretrain_batch)
        steps = int(self.pretrain_epochs) * math.ceil(n / batch)
        optimizer, decay = self._schedule(steps)
        history = []
        epochs = range(int(self.pretrain_epochs))
        for _ in tqdm(epochs, desc="control-space", disable=not self.progress, leave=False):
            order = natural[torch.randperm(n, generator=generator)]
            total = 0.0
            for start in range(0, n, batch):
                rows = order[start : start + batch]
                cost = data.control_cost(self.network_(data.inputs[rows]), rows, data.spread)
                optimizer.zero_grad(set_to_none=True)
                cost.backward()
                optimizer.step()
                decay.step()
                total += float(cost.detach()) * len(rows)
            history.append(_checked(total / n, "control-space", len(history) + 1, self))
        return history

    def _train_joint_space(
        self, forward, data: JointSpaceData, generator
    ) -> list[dict[str, float]]:
        """Joint-space cost through the rig on every row, control term on the known ones."""
        n, batch = len(data.inputs), int(self.batch_size)
        on = data.natural if self.control_rows == "natural" else data.known
        steps = int(self.epochs) * math.ceil(n / batch)
        optimizer, decay = self._joint_schedule(steps)
        history = []
        bar = tqdm(
            total=steps, desc="through the rig", unit="step", disable=not self.progress, leave=False
        )
        for _ in range(int(self.epochs)):
            order = torch.randperm(n, generator=generator)
            sums = {"joint": 0.0, "control": 0.0}
            for start in range(0, n, batch):
                rows = order[start : start + batch]
                joint, control = joint_space_cost(self.network_, forward, data, rows, on)
                cost = joint + float(self.control_weight) * control
                optimizer.zero_grad(set_to_none=True)
                cost.backward()
                optimizer.step()
                decay.step()
                sums["joint"] += float(joint.detach()) * len(rows)
                sums["control"] += float(control.detach()) * len(rows)
                bar.update(1)
            epoch = {k: v / n for k, v in sums.items()}
            _checked(epoch["joint"], "joint-space", len(history) + 1, self)
            history.append(epoch)
        bar.close()
        return history

    # ------------------------------------------------------------------ predict
    def predict(self, X: Any) -> np.ndarray:
        """Targets for ``(M, D)`` inputs (or one ``(D,)`` row); no rig evaluation."""
        if not self.is_fitted():
            raise RuntimeError(f"{type(self).__name__} is not fitted: call fit(X, Y) first")
        X, squeeze = self.fingerprint_.check_inputs(X, type(self).__name__)
        out = np.empty((len(X), self.fingerprint_.output_dim))
        with torch.inference_mode():
            for start in range(0, len(X), _PREDICT_CHUNK):
                x = torch.from_numpy(X[start : start + _PREDICT_CHUNK].astype(np.float32))
                out[start : start + _PREDICT_CHUNK] = self.network_(x).numpy()
        out = self.network_.clip(out)
        return out[0] if squeeze else out

    # ------------------------------------------------------------------ fit stage, files
    def is_fitted(self) -> bool:
        return hasattr(self, "network_")

    def describe_result(self) -> list[str]:
        last = self.history_["joint_space"][-1] if self.history_["joint_space"] else None
        if last is None:
            return ["no joint-space epochs (control-space training only)"]
        return [
            f"joint-space cost of the last epoch: joint {last['joint']:.4g} (per joint-coordinate "
            f"variance), control {last['control']:.4g} (std units)"
        ]

    def fit_facts(self) -> dict[str, Any]:
        """The fit's cost curves and where its time went (draws posed and the training
        tensors and network built, control-space phase, joint-space phase incl. any compile;
        in ``fit.json``, not in the model file, so a refit writes the same model bytes)."""
        facts = {"history": self.history_}
        if getattr(self, "seconds_", None) is not None:
            facts["seconds"] = {k: round(v, 3) for k, v in self.seconds_.items()}
        return {"joint_space_network": facts}

    def _file_meta(self) -> dict[str, Any]:
        return {"history": self.history_, "draws_summary": self.draws_summary_}

    def _payload(self) -> bytes:
        """The network's state dict as npz bytes (plain arrays, no pickle)."""
        state = self.network_.state_dict()
        return model_io.arrays_to_bytes({k: v.detach().numpy() for k, v in state.items()})

    def _restore(self, meta: dict[str, Any], payload: bytes, source: str) -> None:
        fingerprint = self.fingerprint_
        network = SquashedNetwork(
            fingerprint.input_dim, int(self.hidden), int(self.layers), fingerprint.output_dim
        )
        try:
            self.history_ = dict(meta["history"])
            self.draws_summary_ = _checked_summary(meta.get("draws_summary"))
            names = list(network.state_dict())
            arrays = model_io.arrays_from_bytes(payload, source, names)
            network.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})
        except (KeyError, TypeError, ValueError, RuntimeError) as error:
            raise ModelFileError(f"{source}: not a valid {self.name} model ({error})") from None
        network.eval()
        self.network_ = network


def _digest(values: np.ndarray) -> str:
    """SHA-256 of an array's shape and float64 bytes."""
    array = np.ascontiguousarray(values, dtype=np.float64)
    return hashlib.sha256(repr(array.shape).encode() + array.tobytes()).hexdigest()


def draws_summary(values: np.ndarray) -> dict[str, Any]:
    """The draws' shape and each column's mean and std (float64): what
    :func:`same_draws` compares."""
    array = np.asarray(values, dtype=np.float64)
    return {
        "shape": list(array.shape),
        "mean": array.mean(axis=0).tolist(),
        "std": array.std(axis=0).tolist(),
    }


def _checked_summary(summary: Any) -> dict[str, Any] | None:
    """A model file's draws summary as :func:`draws_summary` writes it (``None`` if absent);
    anything else raises ``ValueError`` (the loader names the file)."""
    if summary is None:
        return None
    shape = summary.get("shape") if isinstance(summary, dict) else None
    if not (isinstance(shape, list) and len(shape) == 2 and all(type(n) is int for n in shape)):
        raise ValueError(f"draws_summary must hold a shape [rows, columns], got {summary!r:.80}")
    for key in ("mean", "std"):
        values = summary.get(key)
        if not (isinstance(values, list) and len(values) == shape[1]) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in values
        ):
            raise ValueError(f"draws_summary[{key!r}] must be {shape[1]} numbers")
    return summary


def same_draws(summary: dict[str, Any], values: np.ndarray) -> bool:
    """Whether ``values`` are the draws ``summary`` describes, up to rounding: every
    column's mean and std within 1e-9 of the fit's, relative to the largest of them (ours;
    rounding moves them by ~1e-15, another corpus or seed by far more than 1e-9)."""
    now = draws_summary(values)
    if now["shape"] != list(summary["shape"]):
        return False
    for key in ("mean", "std"):
        then, found = np.asarray(summary[key], dtype=np.float64), np.asarray(now[key])
        size = max(1.0, float(np.abs(then).max(initial=0.0)))
        if then.shape != found.shape or not np.allclose(found, then, rtol=1e-9, atol=1e-9 * size):
            return False
    return True


def _checked(value: float, phase: str, epoch: int, model: Regressor) -> float:
    if not math.isfinite(value):
        raise TrainingDivergedError(
            f"{type(model).__name__}: {phase} training diverged, the cost of epoch {epoch} is "
            f"{value} (learning_rate={model.learning_rate}); lower regressor.learning_rate. "
            "Nothing was saved."
        )
    return value
