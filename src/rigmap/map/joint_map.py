"""Skeleton correspondence as data: which source joint drives which rig joint, and how.

A joint map (:class:`JointMap`; its files and messages keep the user-facing name "retarget
map": ``conf/retarget/<name>.yaml``, ``map.retarget``) says, for one source skeleton and one
rig: the rig joints it drives and the source joint that drives each; the source's axes
(which signed axis is up, forward and the character's left); and the scale. The rig's
own conventions (Y up, facing +Z, left +X, centimetres) are the target.

Applying it rebuilds the mapped rig joints along the source's bone directions with the
rig's own bone lengths (``preserve_lengths: true``), so a mocap skeleton of other
proportions, in any rest pose (T or A), gives joint positions the rig can reach; the
root follows the source's root, scaled. The rebuild, the ``auto`` scale (ratio of
summed bone lengths over the mapped bones) and the ground alignment are our choices:
the paper (§6.3, Fig. 8) gives no retargeting details.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.map.tracks import LENGTH_UNITS_CM, SOURCE_UNIT, JointTracks
from rigmap.store import read_data_file

RIG_AXES = {"left": 0, "up": 1, "forward": 2}  # rig x = left, y = up, z = forward
AXIS_NAMES = {"x": 0, "y": 1, "z": 2}
DEGENERATE_FRACTION = 1e-6  # a source bone this much shorter than the longest has no direction
GROUND_PERCENTILE = 5.0  # the clip's "on the floor" height of its lowest joint (ours)


class JointMapError(RigmapError, ValueError):
    """A retarget map that does not fit its rig or its source; names the file and the joint."""


@dataclass(frozen=True)
class MappedTargets:
    """Rig-joint targets from a source: ``positions[f, k]`` is rig joint ``joint_names[k]``
    in world centimetres, rig axes. ``undriven`` rig joints and ``unused`` source joints are
    listed, never silently dropped."""

    rig: str
    joint_names: tuple[str, ...]
    positions: np.ndarray
    fps: float
    source: str
    scale: float
    undriven: tuple[str, ...]
    unused: tuple[str, ...]


@dataclass(frozen=True)
class JointMap:
    """Source skeleton → rig: joint pairs, source axes, scale; see the module docstring."""

    name: str
    rig: str
    joints: Mapping[str, str]
    up: str = "+y"
    forward: str = "+z"
    left: str = "+x"
    scale: float | str = "auto"
    preserve_lengths: bool = True
    ground: str = "align"
    ignore: tuple[str, ...] = ()
    source_file: str = "<retarget map>"
    _matrix: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        where = self.source_file
        if not self.joints:
            raise JointMapError(f"{where}: 'joints' is empty; map at least the rig's root")
        object.__setattr__(self, "joints", dict(self.joints))
        object.__setattr__(self, "ignore", tuple(self.ignore))
        object.__setattr__(self, "_matrix", self._axes_matrix())
        if not (self.scale in ("auto", "unit") or _positive_number(self.scale)):
            raise JointMapError(
                f"{where}: scale {self.scale!r} must be 'auto' (from bone lengths), 'unit' (the "
                "tracks' stated unit) or a positive number of rig cm per source unit"
            )
        if self.ground not in ("align", "keep"):
            raise JointMapError(f"{where}: ground {self.ground!r} must be 'align' or 'keep'")

    # --- reading -------------------------------------------------------------------------
    @classmethod
    def from_yaml(cls, path: str | os.PathLike) -> JointMap:
        data = read_data_file(path, "retarget map", JointMapError)
        return cls.from_mapping(data, source_file=str(path))

    @classmethod
    def from_mapping(cls, data, *, source_file: str = "<retarget map>") -> JointMap:
        if not isinstance(data, Mapping):
            raise JointMapError(f"{source_file}: expected a mapping, got {type(data).__name__}")
        allowed = {
            "name",
            "rig",
            "joints",
            "up",
            "forward",
            "left",
            "scale",
            "preserve_lengths",
            "ground",
            "ignore",
        }
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise JointMapError(f"{source_file}: unknown keys {unknown}; allowed {sorted(allowed)}")
        for key in ("rig", "joints"):
            if key not in data:
                raise JointMapError(f"{source_file}: missing key {key!r}")
        joints = data["joints"]
        if not isinstance(joints, Mapping) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in joints.items()
        ):
            raise JointMapError(f"{source_file}: 'joints' must map rig joint names to source names")
        options = {k: v for k, v in data.items() if k not in ("joints", "ignore")}
        options.setdefault("name", Path(source_file).stem)
        return cls(
            joints=joints,
            ignore=tuple(data.get("ignore") or ()),
            source_file=source_file,
            **options,
        )

    # --- axes ----------------------------------------------------------------------------
    def _axes_matrix(self) -> np.ndarray:
        """``M`` with ``rig_vector = M @ source_vector`` (a signed permutation)."""
        matrix = np.zeros((3, 3))
        for role, row in RIG_AXES.items():
            spec = str(getattr(self, role)).strip().lower()
            sign = -1.0 if spec.startswith("-") else 1.0
            axis = spec.lstrip("+-")
            if axis not in AXIS_NAMES:
                raise JointMapError(
                    f"{self.source_file}: {role} axis {spec!r} must be one of "
                    "+x, -x, +y, -y, +z, -z"
                )
            matrix[row, AXIS_NAMES[axis]] = sign
        if not np.allclose(np.abs(matrix).sum(axis=0), 1.0):
            raise JointMapError(
                f"{self.source_file}: up {self.up!r}, forward {self.forward!r} and left "
                f"{self.left!r} must name three different source axes"
            )
        return matrix

    @property
    def axes_matrix(self) -> np.ndarray:
        return self._matrix.copy()

    # --- applying ------------------------------------------------------------------------
    def apply(self, rig, tracks: JointTracks) -> MappedTargets:
        """The mapped rig joints' world positions for every frame of ``tracks``."""
        if rig.name != self.rig:
            raise JointMapError(
                f"{self.source_file}: the map is for rig {self.rig!r}, not {rig.name!r}"
            )
        rig_names, edges = self._edges(rig)
        unused = self._check_source(tracks)
        source = tracks.subset([self.joints[n] for n in rig_names]).positions @ self._matrix.T
        rest = np.asarray(rig.evaluate(rig.controls.defaults[None]), dtype=np.float64)[0]
        rest = rest[[rig.joint_names.index(n) for n in rig_names]]
        source_lengths = self._source_lengths(source, edges, rig_names)
        scale = self._scale(tracks, edges, rest, source_lengths)
        positions = self._rebuild(source, edges, rest, scale, tracks.source, rig_names)
        if self.ground == "align":
            positions = _align_ground(positions, rest, rig)
        undriven = tuple(n for n in rig.joint_names if n not in self.joints)
        if unused:
            warnings.warn(
                f"{tracks.source}: source joints {list(unused)} drive no rig joint under "
                f"{self.source_file} (add them to 'joints', or to 'ignore' to silence this)",
                stacklevel=2,
            )
        return MappedTargets(
            rig.name,
            tuple(rig_names),
            positions,
            tracks.fps,
            tracks.source,
            scale,
            undriven,
            unused,
        )

    def _edges(self, rig) -> tuple[list[str], list[tuple[int, int]]]:
        """Mapped rig joints in hierarchy order and (parent, child) pairs between them."""
        unknown = sorted(n for n in self.joints if n not in rig.joint_names)
        if unknown:
            raise JointMapError(f"{self.source_file}: rig {rig.name!r} has no joints {unknown}")
        if rig.parents is None:
            raise JointMapError(f"{self.source_file}: rig {rig.name!r} has no joint hierarchy")
        names = [n for n in rig.joint_names if n in self.joints]
        position = {n: k for k, n in enumerate(names)}
        edges, roots = [], []
        for k, name in enumerate(names):
            ancestor = int(rig.parents[rig.joint_names.index(name)])
            while ancestor >= 0 and rig.joint_names[ancestor] not in position:
                ancestor = int(rig.parents[ancestor])
            if ancestor < 0:
                roots.append(name)
            else:
                edges.append((position[rig.joint_names[ancestor]], k))
        if len(roots) != 1:
            raise JointMapError(
                f"{self.source_file}: mapped rig joints {roots} have no mapped ancestor; exactly "
                "one (the rig's root joint) may, so that every other joint hangs from it"
            )
        return names, _topological(edges)

    def _check_source(self, tracks: JointTracks) -> tuple[str, ...]:
        missing = {r: s for r, s in self.joints.items() if s not in tracks.joint_names}
        if missing:
            raise JointMapError(
                f"{tracks.source}: source joints required by {self.source_file} are missing: "
                + ", ".join(f"{s!r} (drives {r!r})" for r, s in missing.items())
            )
        used = set(self.joints.values()) | set(self.ignore)
        return tuple(n for n in tracks.joint_names if n not in used)

    def _source_lengths(self, source, edges, names) -> np.ndarray:
        """Per edge and frame, the source bone's length; a bone with no length is an error."""
        lengths = np.stack(
            [np.linalg.norm(source[:, c] - source[:, p], axis=1) for p, c in edges], axis=1
        )
        floor = DEGENERATE_FRACTION * max(float(lengths.max()), 1e-300)
        frame, edge = np.unravel_index(int(np.argmin(lengths)), lengths.shape)
        if lengths[frame, edge] <= floor:
            parent, child = edges[edge]
            raise JointMapError(
                f"{self.source_file}: rig bone {names[parent]!r} -> {names[child]!r} maps to "
                f"source {self.joints[names[parent]]!r} -> {self.joints[names[child]]!r}, which "
                f"has no length at frame {frame}; map one of them to another source joint"
            )
        return lengths

    def _scale(self, tracks, edges, rest, source_lengths) -> float:
        """Rig cm per source unit: stated, from the tracks' unit, or from bone lengths."""
        if _positive_number(self.scale):
            return float(self.scale)
        if self.scale == "unit":
            if tracks.unit == SOURCE_UNIT:
                raise JointMapError(
                    f"{self.source_file}: scale 'unit' but {tracks.source} has no stated unit; "
                    "use scale: auto"
                )
            return LENGTH_UNITS_CM[tracks.unit]
        rig_total = sum(float(np.linalg.norm(rest[c] - rest[p])) for p, c in edges)
        source_total = float(np.median(source_lengths, axis=0).sum())
        return rig_total / source_total

    def _rebuild(self, source, edges, rest, scale, where, names) -> np.ndarray:
        """The root scaled; every other joint along its source bone, at the rig's length."""
        out = np.empty_like(source)
        root = next(k for k in range(len(names)) if all(c != k for _, c in edges))
        out[:, root] = source[:, root] * scale
        for parent, child in edges:  # in topological order: a parent is placed before its child
            bone = source[:, child] - source[:, parent]
            if self.preserve_lengths:
                length = np.linalg.norm(rest[child] - rest[parent])
                bone = bone / np.linalg.norm(bone, axis=1, keepdims=True) * length
            else:
                bone = bone * scale
            out[:, child] = out[:, parent] + bone
        if not np.isfinite(out).all():
            raise JointMapError(f"{where}: the retargeted positions are not finite")
        return out


def _topological(edges: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Edges ordered so every parent is placed before its children (a rig may list a
    child before its parent, as Rigify's fingers before their palm bones)."""
    parent_of = {child: parent for parent, child in edges}

    def depth(joint: int) -> int:
        steps = 0
        while joint in parent_of:
            joint, steps = parent_of[joint], steps + 1
        return steps

    return sorted(edges, key=lambda edge: depth(edge[1]))


def _align_ground(positions: np.ndarray, rest: np.ndarray, rig) -> np.ndarray:
    """Shift the clip vertically so its lowest joint rests where the rig's does at rest.

    The rig's rest positions are COG-relative; its COG height comes from a rest pose.
    """
    pose = rig.pose(rig.controls.defaults[None])
    rest_floor = float(np.min(rest[:, 1]) + np.asarray(pose.cog, dtype=np.float64)[0, 1])
    lowest = positions[:, :, 1].min(axis=1)
    shifted = positions.copy()
    shifted[:, :, 1] += rest_floor - float(np.percentile(lowest, GROUND_PERCENTILE))
    return shifted


def _positive_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and value > 0
