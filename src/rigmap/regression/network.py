"""The feed-forward network inverse mapping (paper §5.3).

``Phi(x) = W1 ReLU(W0 x + b0) + b1`` with one hidden layer of 2 048 units,
trained with Adam on minibatches of 8 for 20 epochs, on data standardised by
mean and std, minimising ``||y - Phi(x)||^2 + alpha ||theta||_1``.

How the cost is reduced (``cost_reduction``):

- ``"mean"`` (default): squared error averaged over outputs and examples, plus
  ``alpha`` times the mean absolute value of each parameter tensor, averaged
  over the four tensors ``W0, b0, W1, b1``. This is how the Theano
  ``AdamTrainer`` of the first author's earlier motion-synthesis code writes
  the cost (``mean((Phi - y)^2) + gamma * mean_over_tensors(mean(|p|))`` with
  ``gamma = 0.1``), which we take as the intended reading; it trains well.
- ``"sum"``: Eq. 15 literally per example — squared error summed over outputs,
  averaged over the minibatch, plus ``alpha * ||theta||_1`` summed over all
  ~10^6 parameters. With ``alpha = 0.1`` the L1 term then dominates and drives
  nearly every weight to zero, so it is offered only for comparison.

The L1 term's gradient ``alpha * sign(theta)`` (scaled as above) is added to
the parameter gradients directly instead of differentiating ``|theta|`` through
autograd; it is the same subgradient and saves a pass over the parameters per
step, which matters because a batch-8 step is bound by memory traffic.

Prediction folds the input and output standardisation into the weights, so a
clip is two matrix products in float32 with no per-frame work.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import torch
from tqdm.auto import tqdm

from rigmap.errors import RigmapError
from rigmap.regression import model_io
from rigmap.regression.base import Regressor
from rigmap.regression.errors import ModelFileError
from rigmap.regression.fingerprint import ModelFingerprint
from rigmap.regression.normalisation import column_scale
from rigmap.regression.validation import check_training_data
from rigmap.torch_threads import torch_threads

CostReduction = Literal["mean", "sum"]


class TrainingDivergedError(RigmapError, ArithmeticError):
    """The training cost became NaN or infinite (e.g. a far too large learning rate)."""


_PREDICT_CHUNK = 65_536


class OneHiddenLayer(torch.nn.Module):
    """Eq. 14 with the paper's names for the parameters, initialised from a seeded generator.

    The initial weights are uniform in ``±1/sqrt(fan_in)`` (PyTorch's default
    for linear layers), drawn from ``generator`` so no global RNG is touched.
    """

    def __init__(self, n_inputs: int, n_hidden: int, n_outputs: int, generator: torch.Generator):
        super().__init__()

        def uniform(shape: tuple[int, ...], fan_in: int) -> torch.nn.Parameter:
            bound = 1.0 / math.sqrt(fan_in)
            values = torch.empty(shape).uniform_(-bound, bound, generator=generator)
            return torch.nn.Parameter(values)

        self.W0 = uniform((n_hidden, n_inputs), n_inputs)
        self.b0 = uniform((n_hidden,), n_inputs)
        self.W1 = uniform((n_outputs, n_hidden), n_hidden)
        self.b1 = uniform((n_outputs,), n_hidden)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        hidden = torch.addmm(self.b0, x, self.W0.T).relu_()
        return torch.addmm(self.b1, hidden, self.W1.T)


@dataclass(eq=False, repr=False)
class FeedForwardRegressor(Regressor):
    """Network inverse mapping: joint positions ``(N, D)`` -> controls ``(N, C)`` (§5.3).

    Parameters (the paper's values are the defaults, except where it gives none):

    - ``hidden``: hidden units ``h`` (2 048).
    - ``alpha``: weight of the L1 sparsity term (0.1).
    - ``cost_reduction``: how the cost is averaged; see the module docstring.
    - ``learning_rate``: Adam's step size; the paper does not give one, 1e-3 is
      Adam's usual default.
    - ``batch_size``, ``epochs``: 8 and 20.
    - ``seed``: initial weights and minibatch order (a private torch generator).
    - ``progress``: tqdm bar over training steps.
    - ``threads``: torch intra-op threads while training (``None``: leave
      torch's setting). One by default: a batch-8 step is too small to split,
      and on a busy 2-core machine two threads made it ~9x slower (measured).
      Prediction is untouched and uses every thread.
    """

    name = "nn"
    legacy_names = ("network",)  # model folders written before the one-name change

    hidden: int = 2048
    alpha: float = 0.1
    cost_reduction: CostReduction = "mean"
    learning_rate: float = 1e-3
    batch_size: int = 8
    epochs: int = 20
    seed: int = 0
    progress: bool = True
    threads: int | None = 1

    repr_params = ("hidden", "alpha", "batch_size", "epochs")

    def _check_params(self) -> None:
        for name in ("hidden", "batch_size"):
            if int(getattr(self, name)) < 1:
                raise ValueError(
                    f"FeedForwardRegressor: {name} must be >= 1, got {getattr(self, name)}"
                )
        if int(self.epochs) < 0:
            raise ValueError(f"FeedForwardRegressor: epochs must be >= 0, got {self.epochs}")
        if not (math.isfinite(self.alpha) and self.alpha >= 0):
            raise ValueError(f"FeedForwardRegressor: alpha must be >= 0, got {self.alpha}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(
                f"FeedForwardRegressor: learning_rate must be > 0, got {self.learning_rate}"
            )
        if self.cost_reduction not in ("mean", "sum"):
            raise ValueError(
                "FeedForwardRegressor: cost_reduction must be 'mean' or 'sum', "
                f"got {self.cost_reduction!r}"
            )

    # ------------------------------------------------------------------ fit
    def fit(
        self,
        X: Any,
        Y: Any,
        *,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> FeedForwardRegressor:
        """Train from scratch; ``rig_name``/``control_names`` go into the fingerprint."""
        self._check_params()
        X, Y2 = check_training_data(X, Y, "FeedForwardRegressor")
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], Y2.shape[1], rig_name, control_names)
        self.output_was_vector_ = np.ndim(Y) == 1
        self.x_mean_, self.x_std_ = column_scale(X)
        self.y_mean_, self.y_std_ = column_scale(Y2)
        inputs = torch.from_numpy(((X - self.x_mean_) / self.x_std_).astype(np.float32))
        targets = torch.from_numpy(((Y2 - self.y_mean_) / self.y_std_).astype(np.float32))

        generator = torch.Generator().manual_seed(int(self.seed))
        self.network_ = OneHiddenLayer(X.shape[1], int(self.hidden), Y2.shape[1], generator)
        with torch_threads(self.threads), _deterministic_algorithms():
            self.loss_history_ = self._train(inputs, targets, generator)
        self._folded = None
        return self

    def _train(
        self, inputs: torch.Tensor, targets: torch.Tensor, generator: torch.Generator
    ) -> list[float]:
        """Adam over shuffled minibatches; returns the mean data cost of each epoch."""
        network = self.network_
        parameters = list(network.parameters())
        l1_weights = self._l1_weights(parameters)
        optimizer = _adam(parameters, float(self.learning_rate))
        n, batch = len(inputs), int(self.batch_size)
        steps_per_epoch = math.ceil(n / batch)
        # "mean": squared error averaged over outputs as well as examples
        error_scale = 1.0 / targets.shape[1] if self.cost_reduction == "mean" else 1.0
        history = []
        bar = tqdm(
            total=int(self.epochs) * steps_per_epoch,
            desc="network training",
            unit="step",
            disable=not self.progress,
            mininterval=1.0,
            leave=False,
        )
        network.train()
        for epoch in range(int(self.epochs)):
            order = torch.randperm(n, generator=generator)
            shuffled_inputs, shuffled_targets = inputs[order], targets[order]
            total = torch.zeros(())
            for start in range(0, n, batch):
                x = shuffled_inputs[start : start + batch]
                y = shuffled_targets[start : start + batch]
                error = (network(x) - y).square_().sum(dim=1).mean() * error_scale
                optimizer.zero_grad(set_to_none=True)
                error.backward()
                if self.alpha:
                    with torch.no_grad():
                        for p, weight in zip(parameters, l1_weights, strict=True):
                            p.grad.add_(p.sign(), alpha=weight)
                optimizer.step()
                total += error.detach() * len(x)
                bar.update(1)
            history.append(float(total) / n)
            bar.set_postfix(epoch=epoch + 1, error=f"{history[-1]:.4g}")
            if not math.isfinite(history[-1]):
                bar.close()
                raise TrainingDivergedError(
                    f"FeedForwardRegressor: training diverged, the cost of epoch {epoch + 1} is "
                    f"{history[-1]} (learning_rate={self.learning_rate}); lower "
                    "regressor.learning_rate. Nothing was saved."
                )
        bar.close()
        network.eval()
        return history

    def cost(self, X: Any, Y: Any) -> dict[str, float]:
        """The training cost's two terms on ``(X, Y)`` under ``cost_reduction``."""
        self._check_fitted()
        X, _ = self.fingerprint_.check_inputs(X, "FeedForwardRegressor")
        Y2 = np.asarray(Y, dtype=np.float64).reshape(len(X), -1)
        with torch.inference_mode():
            inputs = torch.from_numpy(((X - self.x_mean_) / self.x_std_).astype(np.float32))
            targets = torch.from_numpy(((Y2 - self.y_mean_) / self.y_std_).astype(np.float32))
            squared = float((self.network_(inputs) - targets).square().sum(dim=1).mean())
            parameters = list(self.network_.parameters())
            l1 = sum(
                weight * float(p.abs().sum())
                for p, weight in zip(parameters, self._l1_weights(parameters), strict=True)
            )
        if self.cost_reduction == "mean":
            squared /= Y2.shape[1]
        return {"error": squared, "l1": l1}

    def _l1_weights(self, parameters: list[torch.nn.Parameter]) -> list[float]:
        """Per-tensor factor on ``sum |p|`` that makes the L1 term of the chosen reduction."""
        if self.cost_reduction == "mean":
            return [float(self.alpha) / (len(parameters) * p.numel()) for p in parameters]
        return [float(self.alpha)] * len(parameters)

    # ------------------------------------------------------------------ predict
    def predict(self, X: Any) -> np.ndarray:
        """Controls for a batch ``(M, D)`` (or one ``(D,)`` row), computed in float32.

        Returned as float64 so downstream code sees one dtype whatever the regressor.
        """
        self._check_fitted()
        X, squeeze = self.fingerprint_.check_inputs(X, "FeedForwardRegressor")
        W0, b0, W1, b1 = self._folded_weights()
        out = np.empty((len(X), self.fingerprint_.output_dim))
        with torch.inference_mode():
            for start in range(0, len(X), _PREDICT_CHUNK):
                x = torch.from_numpy(X[start : start + _PREDICT_CHUNK].astype(np.float32))
                hidden = torch.addmm(b0, x, W0).relu_()
                out[start : start + _PREDICT_CHUNK] = torch.addmm(b1, hidden, W1).numpy()
        if self.output_was_vector_:
            out = out[:, 0]
        return out[0] if squeeze else out

    def _folded_weights(self) -> tuple[torch.Tensor, ...]:
        """Weights with standardisation folded in: raw x in, raw y out (transposed for addmm)."""
        if getattr(self, "_folded", None) is None:
            net = self.network_
            with torch.no_grad():
                x_mean, x_std = (torch.from_numpy(v) for v in (self.x_mean_, self.x_std_))
                y_mean, y_std = (torch.from_numpy(v) for v in (self.y_mean_, self.y_std_))
                W0 = net.W0.double() / x_std
                b0 = net.b0.double() - W0 @ x_mean
                W1 = net.W1.double() * y_std[:, None]
                b1 = net.b1.double() * y_std + y_mean
            self._folded = tuple(
                t.float().contiguous() for t in (W0.T.contiguous(), b0, W1.T.contiguous(), b1)
            )
        return self._folded

    def _check_fitted(self) -> None:
        if not hasattr(self, "network_"):
            raise RuntimeError("FeedForwardRegressor is not fitted: call fit(X, Y) first")

    # ------------------------------------------------------------------ fit stage, files
    def fit_facts(self) -> dict[str, Any]:
        return {"network": {"loss_history": [float(v) for v in self.loss_history_]}}

    def is_fitted(self) -> bool:
        return hasattr(self, "network_")

    def _file_meta(self) -> dict[str, Any]:
        return {
            "output_was_vector": bool(self.output_was_vector_),
            "loss_history": list(self.loss_history_),
        }

    def _payload(self) -> bytes:
        """The network's state dict plus the standardisation, as npz bytes (plain arrays)."""
        state = {name: v.detach().numpy() for name, v in self.network_.state_dict().items()}
        for name in ("x_mean", "x_std", "y_mean", "y_std"):
            state[name] = np.asarray(getattr(self, f"{name}_"))
        return model_io.arrays_to_bytes(state)

    def _restore(self, meta: dict[str, Any], payload: bytes, source: str) -> None:
        try:
            self.output_was_vector_ = bool(meta["output_was_vector"])
            self.loss_history_ = [float(v) for v in meta["loss_history"]]
        except (KeyError, TypeError, ValueError) as error:
            raise ModelFileError(
                f"{source}: metadata is incomplete or invalid ({error!r})"
            ) from None
        fingerprint, hidden = self.fingerprint_, int(self.hidden)
        expected = {
            "W0": (hidden, fingerprint.input_dim),
            "b0": (hidden,),
            "W1": (fingerprint.output_dim, hidden),
            "b1": (fingerprint.output_dim,),
            "x_mean": (fingerprint.input_dim,),
            "x_std": (fingerprint.input_dim,),
            "y_mean": (fingerprint.output_dim,),
            "y_std": (fingerprint.output_dim,),
        }
        arrays = model_io.arrays_from_bytes(payload, source, list(expected))
        state = {name: torch.from_numpy(values) for name, values in arrays.items()}
        for name, shape in expected.items():
            if name not in state or tuple(state[name].shape) != shape:
                found = tuple(state[name].shape) if name in state else "missing"
                raise ModelFileError(f"{source}: tensor {name!r} is {found}, expected {shape}")
        network = OneHiddenLayer(
            fingerprint.input_dim, hidden, fingerprint.output_dim, torch.Generator()
        )
        network.load_state_dict({k: state[k] for k in ("W0", "b0", "W1", "b1")})
        network.eval()
        self.network_ = network
        for name in ("x_mean", "x_std", "y_mean", "y_std"):
            setattr(self, f"{name}_", state[name].numpy().astype(np.float64))
        self._folded = None


def _adam(parameters: list[torch.nn.Parameter], learning_rate: float) -> torch.optim.Adam:
    """Adam with the fused CPU kernel when this torch build has it (one pass per step)."""
    try:
        return torch.optim.Adam(parameters, lr=learning_rate, fused=True)
    except (RuntimeError, TypeError, ValueError):
        return torch.optim.Adam(parameters, lr=learning_rate)


@contextmanager
def _deterministic_algorithms():
    """Torch's deterministic kernels while training: on the CPU ops used here it costs nothing
    (measured: same time, same bits), and an op without one fails instead of varying."""
    previous = torch.are_deterministic_algorithms_enabled()
    _set_deterministic(True)
    try:
        yield
    finally:
        _set_deterministic(previous)


def _set_deterministic(mode: bool) -> None:
    # torch.use_deterministic_algorithms also imports torch._inductor to set its flag, 1.5 s per
    # stage process on this machine (about 30 stages train a network); nothing here compiles
    setter = getattr(torch._C, "_set_deterministic_algorithms", None)
    if setter is None:  # a torch without the private setter: the public call
        torch.use_deterministic_algorithms(mode)
    else:
        setter(mode)
