"""A regressor behind the rig's placement: pose rows in, used controls (or Jacobians) out.

The regressors (GPR, network, learned Jacobian) learn on placement-free inputs
and targets (:mod:`rigmap.regression.placement`); everything outside them —
the evaluation, refinement, the MLflow model — hands over plain pose rows
(``inverse_features``: COG-relative joints, COG position and rotation) and gets
controls in the rig's own terms. These wrappers do the conversion both ways and
save the placement beside the regressor's files (``placement.json``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from rigmap.regression.base import Regressor
from rigmap.regression.errors import ModelFileError
from rigmap.regression.learned_jacobian import LearnedJacobian
from rigmap.regression.placement import Placement
from rigmap.store import write_text_atomic

PLACEMENT_FILE = "placement.json"


def has_placement(folder: str | os.PathLike) -> bool:
    return (Path(folder) / PLACEMENT_FILE).is_file()


def _write_placement(folder: Path, placement: Placement, regressor_file: str) -> None:
    data = {"regressor_file": regressor_file, "placement": placement.to_dict()}
    write_text_atomic(folder / PLACEMENT_FILE, json.dumps(data, indent=2) + "\n")


def _read_placement(folder: Path) -> tuple[str, Placement]:
    path = folder / PLACEMENT_FILE
    try:
        data = json.loads(path.read_text("utf-8"))
        return str(data["regressor_file"]), Placement.from_dict(data["placement"], str(path))
    except FileNotFoundError:
        raise ModelFileError(f"{path}: missing (the model folder has no placement)") from None
    except (KeyError, TypeError, ValueError) as error:
        raise ModelFileError(f"{path}: not a valid placement file ({error})") from None


class _BehindPlacement:
    """A fitted model with the placement it learns behind; unknown attributes are the model's."""

    _inner: ClassVar[str]  # the attribute holding the wrapped model

    def __init__(self, model: Any, placement: Placement):
        setattr(self, self._inner, model)
        self.placement = placement

    def __getattr__(self, name: str) -> Any:
        if name in (self._inner, "placement"):  # not set yet (copy, unpickling)
            raise AttributeError(name)
        return getattr(getattr(self, self._inner), name)

    def _rows(self, X_pose: Any) -> tuple[np.ndarray, bool]:
        X = np.asarray(X_pose, dtype=np.float64)
        return (X[None], True) if X.ndim == 1 else (X, False)

    def save(self, folder: str | os.PathLike) -> Path:
        folder = Path(folder)
        model = getattr(self, self._inner)
        model.save(folder)
        _write_placement(folder, self.placement, model.name)
        return folder


class InverseMapping(_BehindPlacement):
    """``predict(pose rows (N, 3J + 12)) -> used controls (N, C_used)``.

    Attributes the wrapper does not have (``kernel_``, ``length_scale_``,
    ``loss_history_`` …) are the regressor's.
    """

    _inner = "regressor"
    regressor: Regressor

    def __repr__(self) -> str:
        return f"InverseMapping({self.regressor!r}; {self.placement.describe()})"

    def fit(self, X_pose: Any, Y_used: Any, **options: Any) -> InverseMapping:
        inputs = self.placement.inputs(X_pose, "training rows")
        targets = self.placement.targets(Y_used, X_pose, "training rows")
        self.regressor.fit(inputs, targets, **options)
        return self

    def predict(self, X_pose: Any) -> np.ndarray:
        X, single = self._rows(X_pose)
        where = f"{type(self.regressor).__name__} inverse mapping"
        inputs = self.placement.inputs(X, where)
        Y = self.placement.controls(np.asarray(self.regressor.predict(inputs)), X, where)
        return Y[0] if single else Y

    @classmethod
    def load(cls, folder: str | os.PathLike, rig: Any = None) -> InverseMapping:
        folder = Path(folder)
        name, placement = _read_placement(folder)
        try:
            regressor_class = Regressor.subclass_named(name)
        except ModelFileError as error:
            raise ModelFileError(f"{folder / PLACEMENT_FILE}: regressor_file: {error}") from None
        return cls(regressor_class.load(folder, rig=rig), placement)


class JacobianMapping(_BehindPlacement):
    """``predict(pose rows) -> (N, 3J, C_used)`` Jacobians of the COG-relative joints.

    The learned Jacobian is fitted in the placement's input frame (turned by the
    heading), where it does not depend on which way the character faces; this
    turns its predictions back into the world orientation refinement works in.
    """

    _inner = "learned"
    learned: LearnedJacobian

    def fit(self, X_pose: Any, jacobians: Any, **options: Any) -> JacobianMapping:
        inputs = self.placement.inputs(X_pose, "Jacobian poses")
        turned = self.placement.jacobians_to_inputs_frame(jacobians, X_pose)
        self.learned.fit(inputs, turned, **options)
        return self

    def predict(self, X_pose: Any) -> np.ndarray:
        """World-oriented Jacobians ``(N, 3J, C)`` at pose rows ``(N, 3J + 12)``.

        The turn is applied to the predicted entries alone (each joint's three rows of
        a column that any of them has in the pattern, 16 % of the quadruped's dense
        Jacobian), not to the dense arrays: the same numbers as
        ``placement.jacobians_to_world`` of the dense prediction, for 75 quadruped
        frames about 3 ms instead of 10 (ours; ``tests/test_regression.py``).
        """
        X, single = self._rows(X_pose)
        inputs = self.placement.inputs(X, "learned Jacobian")
        rows, columns = self.learned.jacobian_shape_
        if self.placement.turn is None or rows != 3 * self.placement.n_joints:
            J = self.placement.jacobians_to_world(self.learned.predict(inputs), X)
            return J[0] if single else J
        values = self.learned.predict_entries(inputs)
        slots, targets = self._turn_slots()
        padded = np.concatenate([values, np.zeros((len(values), 1))], axis=1)
        R = self.placement.turns_of(X)
        # each (joint, column)'s three rows turned: a batched (G, 3) @ (3, 3) product (numpy's
        # einsum of the same took 20 ms for 72 quadruped frames, matmul 1.2)
        turned = np.matmul(padded[:, slots], R.transpose(0, 2, 1))
        flat = np.zeros((len(X), rows * columns))
        flat[:, targets] = turned.reshape(len(X), -1)
        J = flat.reshape(len(X), rows, columns)
        return J[0] if single else J

    def _turn_slots(self) -> tuple[np.ndarray, np.ndarray]:
        """``(G, 3)`` positions in ``predict_entries``' values (``E``: a zero) of the x, y, z
        rows of every (joint, column) with a predicted entry, and their ``(G·3,)`` flat
        indices in the dense Jacobian (cached)."""
        cached = self.__dict__.get("_slots")
        entries = self.learned.nonzero_entries()
        if cached is not None and cached[0] is entries:
            return cached[1], cached[2]
        columns = self.learned.jacobian_shape_[1]
        row, column = np.divmod(entries, columns)
        joint = row // 3
        groups, group_of = np.unique(joint * columns + column, return_inverse=True)
        slots = np.full((len(groups), 3), len(entries))
        slots[group_of, row % 3] = np.arange(len(entries))
        g_joint, g_column = np.divmod(groups, columns)
        targets = ((3 * g_joint[:, None] + np.arange(3)) * columns + g_column[:, None]).ravel()
        self.__dict__["_slots"] = (entries, slots, targets)
        return slots, targets

    @classmethod
    def load(cls, folder: str | os.PathLike, rig: Any = None) -> JacobianMapping:
        folder = Path(folder)
        _, placement = _read_placement(folder)
        return cls(LearnedJacobian.load(folder, rig=rig), placement)
