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
from typing import Any

import numpy as np

from rigmap.regression import REGRESSORS
from rigmap.regression.gpr import ModelFileError, write_atomic
from rigmap.regression.learned_jacobian import LearnedJacobian
from rigmap.regression.placement import Placement

PLACEMENT_FILE = "placement.json"
_REGRESSOR_CLASSES = {cls.file_stem: cls for cls in REGRESSORS.values()}


def has_placement(folder: str | os.PathLike) -> bool:
    return (Path(folder) / PLACEMENT_FILE).is_file()


def _write_placement(folder: Path, placement: Placement, regressor_file: str) -> None:
    data = {"regressor_file": regressor_file, "placement": placement.to_dict()}
    write_atomic(folder / PLACEMENT_FILE, (json.dumps(data, indent=2) + "\n").encode("utf-8"))


def _read_placement(folder: Path) -> tuple[str, Placement]:
    path = folder / PLACEMENT_FILE
    try:
        data = json.loads(path.read_text("utf-8"))
        return str(data["regressor_file"]), Placement.from_dict(data["placement"], str(path))
    except FileNotFoundError:
        raise ModelFileError(f"{path}: missing (the model folder has no placement)") from None
    except (KeyError, TypeError, ValueError) as error:
        raise ModelFileError(f"{path}: not a valid placement file ({error})") from None


class InverseMapping:
    """``predict(pose rows (N, 3J + 12)) -> used controls (N, C_used)``.

    Attributes the wrapper does not have (``kernel_``, ``length_scale_``,
    ``loss_history_`` …) are the regressor's.
    """

    file_stem = "mapping"

    def __init__(self, regressor: Any, placement: Placement):
        self.regressor = regressor
        self.placement = placement

    def __getattr__(self, name: str) -> Any:
        if name in ("regressor", "placement"):  # not set yet (copy, unpickling)
            raise AttributeError(name)
        return getattr(self.regressor, name)

    def __repr__(self) -> str:
        return f"InverseMapping({self.regressor!r}; {self.placement.describe()})"

    def fit(self, X_pose: Any, Y_used: Any, **options: Any) -> InverseMapping:
        inputs = self.placement.inputs(X_pose, "training rows")
        targets = self.placement.targets(Y_used, X_pose, "training rows")
        self.regressor.fit(inputs, targets, **options)
        return self

    def predict(self, X_pose: Any) -> np.ndarray:
        X = np.asarray(X_pose, dtype=np.float64)
        single = X.ndim == 1
        X = X[None] if single else X
        where = f"{type(self.regressor).__name__} inverse mapping"
        inputs = self.placement.inputs(X, where)
        Y = self.placement.controls(np.asarray(self.regressor.predict(inputs)), X, where)
        return Y[0] if single else Y

    def save(self, folder: str | os.PathLike) -> Path:
        folder = Path(folder)
        self.regressor.save(folder)
        _write_placement(folder, self.placement, self.regressor.file_stem)
        return folder

    @classmethod
    def load(cls, folder: str | os.PathLike, rig: Any = None) -> InverseMapping:
        folder = Path(folder)
        stem, placement = _read_placement(folder)
        if stem not in _REGRESSOR_CLASSES:
            raise ModelFileError(
                f"{folder / PLACEMENT_FILE}: regressor_file {stem!r} is not one of "
                f"{sorted(_REGRESSOR_CLASSES)}"
            )
        return cls(_REGRESSOR_CLASSES[stem].load(folder, rig=rig), placement)


class JacobianMapping:
    """``predict(pose rows) -> (N, 3J, C_used)`` Jacobians of the COG-relative joints.

    The learned Jacobian is fitted in the placement's input frame (turned by the
    heading), where it does not depend on which way the character faces; this
    turns its predictions back into the world orientation refinement works in.
    """

    file_stem = "jacobian_mapping"

    def __init__(self, learned: LearnedJacobian, placement: Placement):
        self.learned = learned
        self.placement = placement

    def __getattr__(self, name: str) -> Any:
        if name in ("learned", "placement"):
            raise AttributeError(name)
        return getattr(self.learned, name)

    def fit(self, X_pose: Any, jacobians: Any, **options: Any) -> JacobianMapping:
        inputs = self.placement.inputs(X_pose, "Jacobian poses")
        turned = self.placement.jacobians_to_inputs_frame(jacobians, X_pose)
        self.learned.fit(inputs, turned, **options)
        return self

    def predict(self, X_pose: Any) -> np.ndarray:
        X = np.asarray(X_pose, dtype=np.float64)
        single = X.ndim == 1
        X = X[None] if single else X
        J = self.learned.predict(self.placement.inputs(X, "learned Jacobian"))
        J = self.placement.jacobians_to_world(J, X)
        return J[0] if single else J

    def save(self, folder: str | os.PathLike) -> Path:
        folder = Path(folder)
        self.learned.save(folder)
        _write_placement(folder, self.placement, self.learned.file_stem)
        return folder

    @classmethod
    def load(cls, folder: str | os.PathLike, rig: Any = None) -> JacobianMapping:
        folder = Path(folder)
        _, placement = _read_placement(folder)
        return cls(LearnedJacobian.load(folder, rig=rig), placement)
