"""Inverse mappings from a subset of the joints (paper §6.3: Fig. 5 effectors, Fig. 6 feet).

A mocap skeleton drives only the joints it has; a full-body IK tool gives a handful of
effectors; the dog of Fig. 6 is posed from its four feet. A :class:`JointSubset` names
the input joints and the joints that define the subset's own frame, and a
:class:`SubsetMapping` learns controls from them, from the same corpus and samples as
the full mapping.

No source knows the rig's centre of gravity, so the subset carries a *virtual COG*: its
``origin`` joint, turned by the heading of the ``left`` → ``right`` axis on the ground.
Pose rows are built around it exactly as around the real COG (``(N, 3K + 12)``:
joints relative to it, its position, its rotation), so the root channels are solved
from it by the same :class:`rigmap.regression.placement.Placement` and the regressors
stay placement-free.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.regression.features import split_features
from rigmap.regression.mapping import InverseMapping
from rigmap.regression.placement import Placement, find_placement, turn_matrix
from rigmap.store import write_json_atomic

SUBSET_FILE = "joint_subset.json"
SUBSET_FORMAT = "rigmap.joint_subset/1"
UP = 1


class SubsetError(RigmapError, ValueError):
    """A joint subset that does not fit its rig or its input; names the joints."""


@dataclass(frozen=True)
class JointSubset:
    """Input joints of a partial mapping and the three joints that give its frame."""

    name: str
    rig: str
    joints: tuple[str, ...]
    origin: str
    left: str
    right: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints", tuple(self.joints))
        frame = [j for j in (self.origin, self.left, self.right) if j not in self.joints]
        if frame:
            raise SubsetError(
                f"joint subset {self.name!r}: frame joints {frame} must be among its input "
                f"joints {list(self.joints)}"
            )
        if self.left == self.right:
            raise SubsetError(f"joint subset {self.name!r}: left and right are both {self.left!r}")
        if len(set(self.joints)) != len(self.joints):
            raise SubsetError(f"joint subset {self.name!r}: input joints repeat")

    @classmethod
    def from_mapping(cls, data: Mapping, *, name: str, rig) -> JointSubset:
        """From config (``joints``, ``origin``, ``left``, ``right``), checked against ``rig``."""
        missing = [k for k in ("joints", "origin", "left", "right") if k not in data]
        if missing:
            raise SubsetError(f"joint subset {name!r} for rig {rig.name!r} lacks {missing}")
        subset = cls(
            name, rig.name, tuple(data["joints"]), data["origin"], data["left"], data["right"]
        )
        subset.check_rig(rig)
        return subset

    def check_rig(self, rig) -> None:
        if rig.name != self.rig:
            raise SubsetError(
                f"joint subset {self.name!r} is for rig {self.rig!r}, not {rig.name!r}"
            )
        unknown = [j for j in self.joints if j not in rig.joint_names]
        if unknown:
            raise SubsetError(
                f"joint subset {self.name!r}: rig {rig.name!r} has no joints {unknown}"
            )

    def columns(self, rig) -> list[int]:
        """The subset's joints as indices into the rig's joints."""
        return [rig.joint_names.index(j) for j in self.joints]

    # --- pose rows around the virtual COG ------------------------------------------------
    def world_from_pose_rows(self, X_pose: np.ndarray, rig) -> np.ndarray:
        """The subset's world positions ``(N, K, 3)`` from the rig's full pose rows."""
        positions, cog, _ = split_features(np.asarray(X_pose, dtype=np.float64), rig.n_joints)
        return positions[:, self.columns(rig)] + cog[:, None, :]

    def pose_rows(self, world: np.ndarray) -> np.ndarray:
        """``(N, 3K + 12)`` rows: joints relative to the virtual COG, its position, rotation."""
        world = np.asarray(world, dtype=np.float64)
        if world.ndim != 3 or world.shape[1:] != (len(self.joints), 3):
            raise SubsetError(
                f"joint subset {self.name!r}: expected positions (N, {len(self.joints)}, 3) of "
                f"{list(self.joints)}, got {world.shape}"
            )
        if not np.isfinite(world).all():
            frame, joint = np.argwhere(~np.isfinite(world).all(axis=2))[0]
            raise SubsetError(
                f"joint subset {self.name!r}: joint {self.joints[joint]!r} is not finite at "
                f"frame {frame}"
            )
        origin = world[:, self.joints.index(self.origin)]
        rotation = turn_matrix(self.heading(world))
        n = len(world)
        relative = (world - origin[:, None, :]).reshape(n, -1)
        return np.concatenate([relative, origin, rotation.reshape(n, 9)], axis=1)

    def heading(self, world: np.ndarray) -> np.ndarray:
        """Turn about +Y that takes the rig's forward (+Z) to the subset's forward.

        Forward is ``lateral × up`` for the ground-plane lateral axis ``left - right``
        (the rig's left is +X, so at rest lateral = +X and forward = +Z).
        """
        lateral = world[:, self.joints.index(self.left)] - world[:, self.joints.index(self.right)]
        forward_x, forward_z = -lateral[:, 2], lateral[:, 0]
        if np.any(np.hypot(forward_x, forward_z) < 1e-9):
            frame = int(np.argmin(np.hypot(forward_x, forward_z)))
            raise SubsetError(
                f"joint subset {self.name!r}: {self.left!r} and {self.right!r} are vertically "
                f"aligned at frame {frame}; no heading"
            )
        return np.arctan2(forward_x, forward_z)

    def to_dict(self) -> dict:
        return {
            "format": SUBSET_FORMAT,
            "name": self.name,
            "rig": self.rig,
            "joints": list(self.joints),
            "origin": self.origin,
            "left": self.left,
            "right": self.right,
        }

    @classmethod
    def from_dict(cls, data: Mapping, source: str = SUBSET_FILE) -> JointSubset:
        if data.get("format") != SUBSET_FORMAT:
            raise SubsetError(
                f"{source}: format {data.get('format')!r}, expected {SUBSET_FORMAT!r}"
            )
        return cls(
            data["name"],
            data["rig"],
            tuple(data["joints"]),
            data["origin"],
            data["left"],
            data["right"],
        )


class SubsetMapping:
    """Controls from a joint subset's world positions: a regressor around the virtual COG."""

    def __init__(self, subset: JointSubset, mapping: InverseMapping):
        self.subset = subset
        self.mapping = mapping

    @classmethod
    def fit(cls, rig, subset: JointSubset, X_pose, Y_used, regressor, **options) -> SubsetMapping:
        """Fit ``regressor`` on the rig's full pose rows ``X_pose`` cut down to ``subset``."""
        subset.check_rig(rig)
        rows = subset.pose_rows(subset.world_from_pose_rows(X_pose, rig))
        probes = np.asarray(Y_used, dtype=np.float64)[:: max(1, len(Y_used) // 4)][:4]
        full = find_placement(rig, probes)
        placement = Placement(
            len(subset.joints),
            full.n_controls,
            full.ground,
            full.turn,
            full.pivot_rest,
            full.turn_range,
            full.notes,
        )
        mapping = InverseMapping(regressor, placement).fit(rows, Y_used, **options)
        return cls(subset, mapping)

    def predict(self, world: np.ndarray) -> np.ndarray:
        """Used controls ``(N, U)`` from the subset's world positions ``(N, K, 3)``."""
        return self.mapping.predict(self.subset.pose_rows(world))

    def save(self, folder: str | os.PathLike) -> Path:
        folder = Path(folder)
        self.mapping.save(folder)
        write_json_atomic(folder / SUBSET_FILE, self.subset.to_dict())
        return folder

    @classmethod
    def load(cls, folder: str | os.PathLike, rig) -> SubsetMapping:
        folder = Path(folder)
        path = folder / SUBSET_FILE
        if not path.is_file():
            raise SubsetError(f"{folder}: no {SUBSET_FILE}; not a partial-input mapping folder")
        try:
            subset = JointSubset.from_dict(json.loads(path.read_text()), str(path))
        except (json.JSONDecodeError, KeyError) as error:
            raise SubsetError(f"{path}: not a valid joint subset ({error})") from None
        subset.check_rig(rig)
        return cls(subset, InverseMapping.load(folder, rig))
