"""Blendshapes and corrective combination shapes, batched in torch.

A blendshape is a per-vertex offset ``(V, 3)`` (cm) scaled by a weight. The
weight is the slider value *hard-clamped* to the slider's range, the way a
production face rig limits its sliders: past the end of its range a slider
does nothing more (its derivative there is zero). Exactly at a range end the
clamp's gradient is one half (``torch.maximum``/``minimum`` split ties), which
is what a central finite difference measures there too, so autodiff and
finite-difference Jacobians agree even at the rest pose, where most sliders
sit at 0. A combination (corrective) shape fixes what two or three shapes
do badly together (a smile on an open jaw); its weight is the product of its
drivers' clamped weights, so it is active only when all drivers are, and the
rig becomes nonlinear in its controls.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch


@dataclass(frozen=True)
class ShapeSpec:
    """One sculpted offset field with the slider range its weight is clamped to."""

    name: str
    deltas: np.ndarray  # (V, 3) cm
    lower: float = 0.0
    upper: float = 1.0


class Blendshapes:
    """A stack of shapes, each driven by one weight column."""

    def __init__(self, shapes: Sequence[ShapeSpec], n_vertices: int):
        names = [s.name for s in shapes]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate blendshape names in {names}")
        for s in shapes:
            if s.deltas.shape != (n_vertices, 3):
                raise ValueError(
                    f"blendshape {s.name!r}: deltas must be ({n_vertices}, 3), got {s.deltas.shape}"
                )
            if not s.lower < s.upper:
                raise ValueError(f"blendshape {s.name!r}: empty range [{s.lower}, {s.upper}]")
        self.names = names
        self.deltas = (
            np.stack([s.deltas for s in shapes]) if shapes else np.zeros((0, n_vertices, 3))
        )
        self.lower = np.array([s.lower for s in shapes], dtype=np.float64)
        self.upper = np.array([s.upper for s in shapes], dtype=np.float64)

    def __len__(self) -> int:
        return len(self.names)

    def clamp(self, values: torch.Tensor) -> torch.Tensor:
        """``(N, S)`` slider values -> weights clamped to each slider's range."""
        return clamp_between(values, self.lower, self.upper)

    def offsets(self, weights: torch.Tensor, deltas: torch.Tensor) -> torch.Tensor:
        """``(N, S)`` weights, ``(S, V', 3)`` deltas (maybe a vertex subset) -> ``(N, V', 3)``."""
        n, v = weights.shape[0], deltas.shape[1]
        return (weights @ deltas.reshape(deltas.shape[0], -1)).reshape(n, v, 3)


def clamp_between(values: torch.Tensor, lower, upper) -> torch.Tensor:
    """Hard clamp whose gradient at a bound is 1/2 (the central-difference value)."""
    lower = torch.as_tensor(lower, dtype=values.dtype)
    upper = torch.as_tensor(upper, dtype=values.dtype)
    return torch.minimum(torch.maximum(values, lower), upper)


@dataclass(frozen=True)
class CombinationSpec:
    """A corrective shape whose weight is the product of its drivers' weights."""

    name: str
    drivers: tuple[str, ...]
    deltas: np.ndarray  # (V, 3) cm


class CombinationShapes:
    """Correctives driven by products of named driver weights."""

    def __init__(self, shapes: Sequence[CombinationSpec], driver_names: Sequence[str], n_vertices):
        index = {name: i for i, name in enumerate(driver_names)}
        self.names = [s.name for s in shapes]
        self.driver_index: list[list[int]] = []
        for s in shapes:
            missing = [d for d in s.drivers if d not in index]
            if missing:
                raise ValueError(
                    f"combination shape {s.name!r}: unknown drivers {missing}; "
                    f"known: {list(driver_names)[:8]}..."
                )
            if len(s.drivers) < 2:
                raise ValueError(
                    f"combination shape {s.name!r} needs >= 2 drivers, got {s.drivers}"
                )
            if s.deltas.shape != (n_vertices, 3):
                raise ValueError(
                    f"combination shape {s.name!r}: deltas must be ({n_vertices}, 3), "
                    f"got {s.deltas.shape}"
                )
            self.driver_index.append([index[d] for d in s.drivers])
        self.deltas = (
            np.stack([s.deltas for s in shapes]) if shapes else np.zeros((0, n_vertices, 3))
        )

    def __len__(self) -> int:
        return len(self.names)

    def weights(self, driver_weights: torch.Tensor) -> torch.Tensor:
        """``(N, D)`` driver weights -> ``(N, S)`` products."""
        columns = []
        for drivers in self.driver_index:
            w = driver_weights[:, drivers[0]]
            for d in drivers[1:]:
                w = w * driver_weights[:, d]
            columns.append(w)
        if not columns:
            return driver_weights.new_zeros(driver_weights.shape[0], 0)
        return torch.stack(columns, dim=1)
