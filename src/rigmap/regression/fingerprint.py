"""What a fitted model expects, so it refuses inputs or rigs it was not made for."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rigmap.regression.errors import ModelMismatchError, RegressionInputError
from rigmap.regression.validation import as_float_array, check_finite


@dataclass(frozen=True)
class ModelFingerprint:
    """What a fitted model expects, so it refuses inputs or rigs it was not made for.

    ``control_names`` names the outputs (the rig's used controls for an inverse
    mapping); ``rig_name`` is the rig the training data came from. Both are
    optional: synthetic problems have neither.
    """

    input_dim: int
    output_dim: int
    rig_name: str | None = None
    control_names: tuple[str, ...] | None = None

    @classmethod
    def build(
        cls,
        input_dim: int,
        output_dim: int,
        rig_name: str | None = None,
        control_names: Sequence[str] | None = None,
    ) -> ModelFingerprint:
        if control_names is not None:
            control_names = tuple(str(n) for n in control_names)
            if len(control_names) != output_dim:
                raise RegressionInputError(
                    f"control_names: expected {output_dim} names (one per output column), "
                    f"got {len(control_names)}"
                )
        return cls(int(input_dim), int(output_dim), rig_name, control_names)

    def describe(self, model: str) -> str:
        return f"{model} fitted for rig {self.rig_name!r}" if self.rig_name else model

    def check_inputs(self, X: Any, model: str) -> tuple[np.ndarray, bool]:
        """``X`` as a finite float64 ``(M, input_dim)`` array, and whether it was one row."""
        X = as_float_array(X, f"{self.describe(model)}: inputs")
        squeeze = X.ndim == 1
        if squeeze:
            X = X[None]
        if X.ndim != 2 or X.shape[1] != self.input_dim:
            raise RegressionInputError(
                f"{self.describe(model)}: expected inputs of shape (M, {self.input_dim}) "
                f"or ({self.input_dim},), got {tuple(np.shape(X))}"
            )
        check_finite(X, f"{self.describe(model)}: inputs")
        return X, squeeze

    def check_rig(self, rig: Any, source: str) -> None:
        """Raise unless ``rig`` (a Rig or a rig name) is the one this model was fitted for."""
        if rig is None:
            return
        name = rig if isinstance(rig, str) else getattr(rig, "name", None)
        if self.rig_name is not None and name != self.rig_name:
            raise ModelMismatchError(
                f"{source} was fitted for rig {self.rig_name!r}, but it is used with rig {name!r}"
            )
        rig_controls = None if isinstance(rig, str) else getattr(rig, "control_names", None)
        if rig_controls is not None and self.control_names is not None:
            missing = [n for n in self.control_names if n not in set(rig_controls)]
            if missing:
                raise ModelMismatchError(
                    f"{source} predicts controls the rig {name!r} does not have: {missing[:5]}"
                    f"{' …' if len(missing) > 5 else ''} ({len(missing)} of "
                    f"{len(self.control_names)})"
                )

    def to_dict(self) -> dict[str, Any]:
        return {
            "input_dim": self.input_dim,
            "output_dim": self.output_dim,
            "rig_name": self.rig_name,
            "control_names": list(self.control_names) if self.control_names else None,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelFingerprint:
        names = data.get("control_names")
        return cls(
            int(data["input_dim"]),
            int(data["output_dim"]),
            data.get("rig_name"),
            tuple(names) if names else None,
        )
