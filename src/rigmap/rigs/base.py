"""The Rig protocol: controls in, joint positions out, whatever evaluates it.

A rig is a black box ``f: y -> x`` (paper §3.2). Built-in rigs run in-process on
torch and are differentiable; a rig living in a DCC (Blender) runs in worker
processes and is not. Everything downstream (corpus, sampling, regression,
refinement) sees only this protocol.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import asdict, dataclass
from typing import Literal, NamedTuple

import numpy as np

from rigmap.errors import RigmapError

ControlKind = Literal["rotate", "translate", "scale", "scalar"]
CONTROL_KINDS: tuple[str, ...] = ("rotate", "translate", "scale", "scalar")


class RigInputError(RigmapError, ValueError):
    """Controls or positions given to a rig have the wrong shape or bad values."""


class UnknownRigError(RigmapError, KeyError):
    """A rig name that no backend knows."""

    def __str__(self) -> str:  # KeyError quotes its message; we want it plain
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class Control:
    """One animatable channel of the rig.

    ``kind`` is what the number means: ``rotate`` (radians), ``translate``
    (the rig's length unit), ``scale`` (a factor) or ``scalar`` (a custom
    attribute such as IK/FK blend or foot roll). ``lower``/``upper`` are the
    soft range an animator works in, not a hard clamp. ``used`` marks the
    channels the animators actually key (§6.1); learning touches only these.
    """

    name: str
    kind: ControlKind
    default: float
    lower: float
    upper: float
    used: bool
    group: str

    def __post_init__(self) -> None:
        if self.kind not in CONTROL_KINDS:
            raise ValueError(f"control {self.name!r}: kind {self.kind!r} not in {CONTROL_KINDS}")
        if not self.lower <= self.default <= self.upper:
            raise ValueError(
                f"control {self.name!r}: default {self.default} outside "
                f"soft range [{self.lower}, {self.upper}]"
            )


class ControlTable:
    """An ordered table of controls with the columns of DESIGN.md.

    Column vectors (``defaults``, ``lower``, ``upper``, ``used``) are numpy
    arrays in control order, so code can index them with ``used_indices``.
    """

    def __init__(self, controls: list[Control]):
        names = [c.name for c in controls]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"duplicate control names: {duplicates[:10]}")
        self._controls = list(controls)
        self._index = {name: i for i, name in enumerate(names)}
        self.names: list[str] = names
        self.kinds: list[str] = [c.kind for c in controls]
        self.groups: list[str] = [c.group for c in controls]
        self.defaults = np.array([c.default for c in controls], dtype=np.float64)
        self.lower = np.array([c.lower for c in controls], dtype=np.float64)
        self.upper = np.array([c.upper for c in controls], dtype=np.float64)
        self.used = np.array([c.used for c in controls], dtype=bool)
        self.used_indices = np.flatnonzero(self.used)

    def __len__(self) -> int:
        return len(self._controls)

    def __iter__(self):
        return iter(self._controls)

    def __getitem__(self, name: str) -> Control:
        return self._controls[self.index(name)]

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            close = [n for n in self.names if name.split(".")[0] in n][:5]
            hint = f"; similar: {close}" if close else ""
            raise KeyError(f"no control named {name!r}{hint}") from None

    def records(self) -> list[dict]:
        return [asdict(c) for c in self._controls]

    def to_frame(self):
        import pandas as pd

        return pd.DataFrame(self.records())

    def summary(self) -> dict:
        """Counts by kind and by group, total and used."""
        by_kind: dict[str, dict[str, int]] = {}
        by_group: dict[str, dict[str, int]] = {}
        for c in self._controls:
            for table, key in ((by_kind, c.kind), (by_group, c.group)):
                entry = table.setdefault(key, {"total": 0, "used": 0})
                entry["total"] += 1
                entry["used"] += int(c.used)
        return {
            "total": len(self),
            "used": int(self.used.sum()),
            "by_kind": dict(sorted(by_kind.items())),
            "by_group": dict(sorted(by_group.items())),
        }


class Pose(NamedTuple):
    """What one rig evaluation gives.

    ``positions``: ``(N, J, 3)`` joint positions relative to the centre of
    gravity (§3.2). ``cog``: ``(N, 3)`` world position of the centre of
    gravity; ``cog_rotation``: ``(N, 3, 3)`` its world orientation — together
    the COG placement from which root controls can be recovered.
    """

    positions: object
    cog: object
    cog_rotation: object


class Rig(ABC):
    """A rig function ``f``: ``(N, C)`` controls -> ``(N, J, 3)`` positions.

    Subclasses set ``name``, ``controls``, ``joint_names``, ``parents`` (``-1``
    for a root; ``None`` for a mesh rig, which sets ``faces`` instead) and
    implement ``_pose``. ``evaluate`` validates input and keeps the caller's
    array type: numpy in, numpy out; torch in, torch out.
    """

    name: str
    controls: ControlTable
    joint_names: list[str]
    parents: np.ndarray | None = None
    faces: np.ndarray | None = None
    differentiable: bool = False
    # a rig that computes in float32 whatever the controls' dtype (Blender's armatures): its
    # finite-difference Jacobians need a step far above float32's resolution
    # (rigmap.refine.jacobian)
    computes_in_float32: bool = False
    length_unit: str = "cm"
    description: str = ""

    # --- the protocol ---------------------------------------------------
    @property
    def control_names(self) -> list[str]:
        return self.controls.names

    @property
    def used_controls(self) -> list[str]:
        return [self.controls.names[i] for i in self.controls.used_indices]

    @property
    def n_controls(self) -> int:
        return len(self.controls)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def default_controls(self, n: int = 1) -> np.ndarray:
        return np.tile(self.controls.defaults, (n, 1))

    def rest_height(self) -> float:
        """The character's height at its default controls: the vertical (y) extent of its
        joints in the world, in ``length_unit``. Errors divided by it compare across rigs."""
        rest = self.pose(self.controls.defaults[None])
        world = np.asarray(rest.positions)[0] + np.asarray(rest.cog)[0]
        return float(np.ptp(world[:, 1]))

    def evaluate(self, Y):
        """Joint positions relative to the COG, ``(N, J, 3)``."""
        return self.pose(Y).positions

    def pose(self, Y) -> Pose:
        """Positions plus the COG placement, for a batch of control vectors."""
        Y, squeeze = self._check_controls(Y)
        pose = self._pose(Y)
        _check_finite_pose(self.name, pose)
        if squeeze:
            pose = Pose(*(p[0] for p in pose))
        return pose

    @abstractmethod
    def _pose(self, Y) -> Pose:
        """Evaluate a validated ``(N, C)`` batch (numpy or torch)."""

    def close(self) -> None:  # noqa: B027 - optional hook, deliberately not abstract
        """Release resources (worker processes); a no-op for in-process rigs."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"<{type(self).__name__} {self.name!r}: {self.n_joints} joints, "
            f"{self.n_controls} controls ({len(self.used_controls)} used)>"
        )

    # --- helpers for subclasses -------------------------------------------
    def expand_used(self, Y_used):
        """Full control vectors from values of the used controls only.

        Unused controls stay at their defaults (§6.1). ``(N, C_used)`` gives
        ``(N, C)``; one ``(C_used,)`` vector gives one ``(C,)`` vector.
        """
        used = self.controls.used_indices
        if not _is_torch(Y_used):
            Y_used = np.asarray(Y_used, dtype=np.float64)
        if Y_used.ndim == 1:
            return self.expand_used(Y_used[None])[0]
        if Y_used.ndim != 2 or Y_used.shape[1] != len(used):
            raise RigInputError(
                f"rig {self.name!r}: expected used-control values of shape (N, {len(used)}), "
                f"got {tuple(Y_used.shape)}"
            )
        if _is_torch(Y_used):
            import torch

            base = torch.as_tensor(self.controls.defaults, dtype=Y_used.dtype)
            # out-of-place, so autodiff transforms (torch.func) can trace through it
            return base.expand(Y_used.shape[0], -1).index_copy(1, torch.as_tensor(used), Y_used)
        Y_used = np.asarray(Y_used, dtype=np.float64)
        full = np.tile(self.controls.defaults, (Y_used.shape[0], 1))
        full[:, used] = Y_used
        return full

    def _check_controls(self, Y):
        squeeze = False
        if _is_torch(Y):
            if Y.dtype not in _torch_float_types():
                raise RigInputError(
                    f"rig {self.name!r}: controls must be float32 or float64, got {Y.dtype}"
                )
            if Y.ndim == 1:
                Y, squeeze = Y[None], True
            finite = bool(Y.isfinite().all())
        else:
            Y = np.asarray(Y)
            if Y.dtype.kind not in "fiu":
                raise RigInputError(
                    f"rig {self.name!r}: controls must be numbers, got dtype {Y.dtype}"
                )
            if Y.dtype not in (np.float32, np.float64):
                Y = Y.astype(np.float64)
            if Y.ndim == 1:
                Y, squeeze = Y[None], True
            finite = bool(np.isfinite(Y).all())
        if Y.ndim != 2 or Y.shape[1] != self.n_controls:
            raise RigInputError(
                f"rig {self.name!r}: expected controls of shape (N, {self.n_controls}) "
                f"or ({self.n_controls},), got {tuple(Y.shape)}"
            )
        if not finite:
            bad = _first_nonfinite(Y)
            raise RigInputError(
                f"rig {self.name!r}: controls contain NaN or infinity "
                f"(first at row {bad[0]}, control {self.control_names[bad[1]]!r})"
            )
        return Y, squeeze


def check_positions(positions, n_joints: int, where: str) -> np.ndarray:
    """Validate joint positions ``(N, J, 3)`` or flat ``(N, 3J)``; return ``(N, J, 3)``."""
    X = np.asarray(positions, dtype=np.float64)
    if X.ndim == 2 and X.shape[1] == 3 * n_joints:
        X = X.reshape(X.shape[0], n_joints, 3)
    if X.ndim != 3 or X.shape[1:] != (n_joints, 3):
        raise RigInputError(
            f"{where}: expected joint positions of shape (N, {n_joints}, 3) or "
            f"(N, {3 * n_joints}), got {X.shape}"
        )
    if not np.isfinite(X).all():
        row, joint = np.argwhere(~np.isfinite(X))[0][:2]
        raise RigInputError(
            f"{where}: joint positions contain NaN or infinity (first at row {row}, joint {joint})"
        )
    return X


def check_placement(cog, cog_rotation, n: int, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Validate the COG's world placement for ``n`` frames: ``cog`` ``(n, 3)`` (cm) and
    ``cog_rotation`` ``(n, 3, 3)``, both finite; return them as float64 arrays."""
    if cog is None or cog_rotation is None:
        raise RigInputError(
            f"{where}: needs the COG placement: cog (N, 3) and cog_rotation (N, 3, 3)"
        )
    cog = np.asarray(cog, dtype=np.float64)
    cog_rotation = np.asarray(cog_rotation, dtype=np.float64)
    if cog.shape != (n, 3) or cog_rotation.shape != (n, 3, 3):
        raise RigInputError(
            f"{where}: expected cog ({n}, 3) and cog_rotation ({n}, 3, 3) for {n} frames, "
            f"got {cog.shape} and {cog_rotation.shape}"
        )
    if not (np.isfinite(cog).all() and np.isfinite(cog_rotation).all()):
        raise RigInputError(f"{where}: cog or cog_rotation contains NaN or infinity")
    return cog, cog_rotation


def _check_finite_pose(rig_name: str, pose: Pose) -> None:
    """A numpy pose with NaN or infinity is an error naming the first bad row: finite but
    huge controls (far outside the soft ranges) can overflow a rig's trigonometry."""
    positions = pose.positions
    if _is_torch(positions):
        return  # differentiable batches are checked by their callers
    finite = np.isfinite(positions).all(axis=(1, 2)) & np.isfinite(pose.cog).all(axis=1)
    if not finite.all():
        row = int(np.flatnonzero(~finite)[0])
        raise RigInputError(
            f"rig {rig_name!r} gave NaN or infinite joint positions for {int((~finite).sum())} "
            f"of {len(finite)} control rows (first row {row}); are its controls far outside "
            "their soft ranges?"
        )


def _is_torch(x) -> bool:
    return type(x).__module__.startswith("torch")


def _torch_float_types():
    import torch

    return (torch.float32, torch.float64)


def _first_nonfinite(Y) -> tuple[int, int]:
    if _is_torch(Y):
        idx = (~Y.isfinite()).nonzero()[0]
        return int(idx[0]), int(idx[1])
    idx = np.argwhere(~np.isfinite(Y))[0]
    return int(idx[0]), int(idx[1])
