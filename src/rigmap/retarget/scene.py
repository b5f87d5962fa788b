"""The rig as a retarget script sees it: rest layout, targets, controls, read-backs.

A Maya script works on a live scene: it sets a control, asks for a parent's
world matrix (which makes the DG evaluate), sets the next control. Here the
script writes control values into a batch of control vectors and, when it
needs the world transforms the rig produces from what it has written so far,
evaluates the rig once for the whole batch; every such read-back is counted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.retarget.euler import euler_to_matrix
from rigmap.retarget.orient import best_rotation, rotate

ROTATE_CHANNELS = ("rx", "ry", "rz")
TRANSLATE_CHANNELS = ("tx", "ty", "tz")
DEFAULT_ROTATION_ORDER = "xyz"
# a value the script would write into a channel the animators never key
_UNUSED_TOLERANCE = 1e-6


@dataclass(frozen=True)
class WorldTransform:
    """Rotation ``R`` ``(N, 3, 3)`` and position ``t`` ``(N, 3)`` of a transform (cm)."""

    R: np.ndarray
    t: np.ndarray

    def apply(self, point: np.ndarray) -> np.ndarray:
        return rotate(self.R, point) + self.t


class Readback:
    """World transforms of one rig evaluation, converted to numpy on first use."""

    def __init__(self, transforms: dict):
        self._transforms = transforms
        self._cache: dict[str, WorldTransform] = {}

    def names(self) -> list[str]:
        return list(self._transforms)

    def __getitem__(self, name: str) -> WorldTransform:
        if name not in self._cache:
            xf = self._transforms[name]
            self._cache[name] = WorldTransform(
                xf.R.detach().numpy().astype(np.float64), xf.t.detach().numpy().astype(np.float64)
            )
        return self._cache[name]


class ScriptScene:
    """Controls being written for ``N`` frames, the targets they aim for, and the rest layout.

    ``targets`` are world joint positions ``(N, J, 3)`` (cm). Rest orientations
    of the built-in rigs are world-aligned, so the rest layout is a position per
    named transform (``rest[name]``, cm), read from one evaluation at defaults.
    """

    def __init__(self, rig, targets: np.ndarray):
        self.rig = rig
        self.targets = targets
        self.n = len(targets)
        self.controls = rig.default_controls(self.n)
        self.evaluations = 0
        rest = self._evaluate(rig.default_controls(1))
        self.rest = {name: rest[name].t[0] for name in rest.names()}
        self._joints = {name: i for i, name in enumerate(rig.joint_names)}
        self._orders = getattr(rig, "rotation_orders", None) or {}
        self._used = set(rig.used_controls)

    # --- reading ---------------------------------------------------------
    def target(self, joint: str) -> np.ndarray:
        """World target position of ``joint``, ``(N, 3)`` cm."""
        return self.targets[:, self._joints[joint]]

    def rest_offset(self, name: str, relative_to: str) -> np.ndarray:
        """Rest vector from one named transform to another (world-aligned, cm)."""
        return self.rest[name] - self.rest[relative_to]

    def carried_orientation(self, joint: str, carried: tuple[str, ...]) -> np.ndarray:
        """World rotation of ``joint`` from joints it carries rigidly (an orient constraint).

        The best rotation (Kabsch) taking the rest offsets of ``carried`` from
        ``joint`` onto their target offsets.
        """
        rest = np.stack([self.rest_offset(c, joint) for c in carried])
        target = np.stack([self.target(c) - self.target(joint) for c in carried], axis=1)
        return best_rotation(rest, target)

    def evaluate(self) -> Readback:
        """Evaluate the rig on the controls written so far (counts ``N`` evaluations)."""
        return self._evaluate(self.controls)

    def _evaluate(self, controls: np.ndarray) -> Readback:
        transforms = self.rig.world_transforms(controls)
        self.evaluations += len(controls)
        return Readback(transforms)

    # --- writing -----------------------------------------------------------
    def rotation_order(self, control: str) -> str:
        return self._orders.get(control, DEFAULT_ROTATION_ORDER)

    def used_axes(self, control: str) -> str:
        """Which of x, y, z the animators key on ``control``'s rotation, e.g. ``"xz"``."""
        return "".join(
            axis
            for axis, channel in zip("xyz", ROTATE_CHANNELS, strict=True)
            if f"{control}.{channel}" in self._used
        )

    def is_used(self, channel: str) -> bool:
        return channel in self._used

    def set(self, channel: str, values) -> None:
        """Write one channel (used or not: the caller decides) for every frame."""
        self.controls[:, self.rig.controls.index(channel)] = values

    def set_euler(self, control: str, angles: np.ndarray) -> np.ndarray:
        """Write ``(N, 3)`` Euler angles into the used rotation channels; return the local R.

        A nonzero angle for a channel the animators never key means the script
        solved for a rotation the control cannot express: a bug, so it raises.
        """
        self._set_vector(control, ROTATE_CHANNELS, angles)
        return euler_to_matrix(
            self._written(control, ROTATE_CHANNELS), self.rotation_order(control)
        )

    def set_translation(self, control: str, translation: np.ndarray) -> None:
        self._set_vector(control, TRANSLATE_CHANNELS, translation)

    def _set_vector(self, control: str, channels: tuple[str, ...], values: np.ndarray) -> None:
        values = np.broadcast_to(np.asarray(values, dtype=np.float64), (self.n, 3))
        for k, ch in enumerate(channels):
            name = f"{control}.{ch}"
            if name in self._used:
                self.set(name, values[:, k])
            elif np.abs(values[:, k]).max() > _UNUSED_TOLERANCE:
                raise RuntimeError(
                    f"retarget script wrote {np.abs(values[:, k]).max():.3g} into {name!r}, "
                    "which the animators never key; the script must solve for used channels only"
                )

    def _written(self, control: str, channels: tuple[str, ...]) -> np.ndarray:
        columns = [self.rig.controls.index(f"{control}.{ch}") for ch in channels]
        return self.controls[:, columns]
