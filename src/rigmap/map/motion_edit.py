"""Motion editing in joint space, mapped back onto the rig (paper §6.3, Fig. 7).

The paper bends a synthesised walk along a curve and projects it onto terrain with spatial
descriptors, then finds rig controls for the edited joints. :class:`MotionEdit` is a small
stand-in for such a tool, with edits a check can measure: the feet are moved onto a height
field (each foot joint, with the joints below it, up by the terrain under it, so a foot
stays rigid; the rest of the body by the lowest terrain under the feet, so the body rides
the ground and no leg must stretch past its length), and a hand (with the joints below
it) is offset over a window in the middle of the clip, eased in and out. :func:`map_edit`
maps the edited joints back with a full-input :class:`rigmap.map.partial.SubsetMapping`
and refinement, and measures how closely the rig's result follows the edit.

The terrain is ``a · sin(2πx/λ) · cos(2πz/λ)`` (world cm, Y up); its shape and every
default are ours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.map.clip import MapSettings, solve_controls

UP = 1


@dataclass(frozen=True)
class MotionEdit:
    """Feet onto a height field, a hand offset over the middle third of the clip."""

    feet: tuple[str, ...]
    hand: str
    terrain_amplitude_cm: float = 6.0
    terrain_wavelength_cm: float = 120.0
    hand_offset_cm: tuple[float, float, float] = (0.0, 10.0, 8.0)

    def __post_init__(self) -> None:
        if not self.terrain_wavelength_cm > 0:
            raise ValueError(f"terrain wavelength {self.terrain_wavelength_cm} cm must be > 0")
        if len(self.hand_offset_cm) != 3:
            raise ValueError(f"hand offset {self.hand_offset_cm} must be [x, y, z] cm")

    def terrain(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Terrain height (cm) at ground positions ``x``, ``z`` (cm)."""
        k = 2 * np.pi / self.terrain_wavelength_cm
        return self.terrain_amplitude_cm * np.sin(k * x) * np.cos(k * z)

    def hand_window(self, n_frames: int) -> np.ndarray:
        """``(F,)`` weight of the hand offset: 0 outside the middle third, eased to 1 inside."""
        t = np.arange(n_frames) / max(n_frames - 1, 1)
        inside = (t > 1 / 3) & (t < 2 / 3)
        return np.where(inside, np.sin(np.pi * (t - 1 / 3) * 3) ** 2, 0.0)

    def apply(self, world: np.ndarray, rig) -> np.ndarray:
        """The edited copy of world joints ``(F, J, 3)`` of every joint of ``rig``."""
        world = np.array(world, dtype=np.float64, copy=True)
        names = list(rig.joint_names)
        feet = [names.index(f) for f in self.feet]
        lift = self.terrain(world[:, feet, 0], world[:, feet, 2])  # (F, feet)
        chains = [[j, *descendants(rig, names[j])] for j in feet]
        body = np.setdiff1d(np.arange(len(names)), np.concatenate(chains))
        world[:, body, UP] += lift.min(axis=1)[:, None]
        for k, chain in enumerate(chains):
            world[:, chain, UP] += lift[:, k, None]
        hand = [names.index(self.hand), *descendants(rig, self.hand)]
        offset = self.hand_window(len(world))[:, None] * np.asarray(self.hand_offset_cm)
        world[:, hand] += offset[:, None, :]
        return world


def descendants(rig, joint: str) -> list[int]:
    """Indices of every joint below ``joint`` in ``rig``'s hierarchy."""
    parents = np.asarray(rig.parents)
    below, frontier = [], [rig.joint_names.index(joint)]
    while frontier:
        children = [int(c) for c in np.flatnonzero(np.isin(parents, frontier))]
        below += children
        frontier = children
    return below


@dataclass(frozen=True)
class EditResult:
    """The edit's targets, the rig's joints after mapping them back, and how well they agree."""

    original: np.ndarray  # (F, J, 3) world cm
    edited: np.ndarray  # (F, J, 3)
    mapped: np.ndarray  # (F, J, 3) the rig at the mapped controls
    controls: np.ndarray  # (F, C)
    foot_height_error_cm: float  # max |mapped − edited| height of the foot joints
    foot_height_rms_cm: float  # its RMS over frames and feet
    hand_offset_error_cm: float  # max distance of the mapped hand to the edited hand
    body_error_cm: float  # RMS over every joint and frame

    def to_dict(self) -> dict:
        frames = len(self.edited)
        return {
            "frames": frames,
            "foot_height_error_cm": self.foot_height_error_cm,
            "foot_height_rms_cm": self.foot_height_rms_cm,
            "hand_offset_error_cm": self.hand_offset_error_cm,
            "body_error_cm": self.body_error_cm,
        }


def map_edit(
    rig, mapping, world, edit: MotionEdit, settings: MapSettings, *, control_std, hold_values
) -> EditResult:
    """Edit world joints ``(F, J, 3)`` (every rig joint) and map them back with ``mapping``
    (a full-input subset mapping) and ``settings``' refinement."""
    if tuple(mapping.subset.joints) != tuple(rig.joint_names):
        raise ValueError(
            f"map_edit needs a mapping from every joint of {rig.name!r}, got "
            f"subset {mapping.subset.name!r}"
        )
    edited = edit.apply(world, rig)
    Y = solve_controls(rig, mapping, edited, settings, control_std, hold_values, {})
    controls = rig.expand_used(Y)
    pose = rig.pose(controls)
    mapped = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
    names = list(rig.joint_names)
    feet = [names.index(f) for f in edit.feet]
    hand = names.index(edit.hand)
    height = np.abs(mapped[:, feet, UP] - edited[:, feet, UP])
    return EditResult(
        np.asarray(world, dtype=np.float64),
        edited,
        mapped,
        controls,
        float(height.max()),
        float(np.sqrt((height**2).mean())),
        float(np.linalg.norm(mapped[:, hand] - edited[:, hand], axis=1).max()),
        float(np.sqrt(((mapped - edited) ** 2).sum(axis=2).mean())),
    )
