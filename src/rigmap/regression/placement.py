"""Where the character stands and faces: root controls solved analytically, not regressed.

A regressor should not care where on the ground a character is or which way it
faces. Training clips cover a few metres and headings; held-out clips travel and
turn anywhere (§6.1's "large, fast or extreme" motions), so world position and
heading as inputs are extrapolated and drag every predicted control with them.

Rigs place the whole character with a root control: two ground-plane
translations and a turn about the vertical axis. :func:`find_placement` finds
those channels on the rig as a black box — a channel that moves or turns the
whole pose rigidly, by the same amount in every probe pose — and
:class:`Placement` then

- gives the regressor inputs that ignore them (:meth:`Placement.inputs`):
  COG-relative joints turned into the COG's heading frame, the COG's height and
  its rotation relative to its heading;
- turns the root channels into targets that do not depend on them either
  (:meth:`Placement.targets`): the root pivot's offset from the COG in the
  heading frame, and the COG's heading relative to the root's;
- and back (:meth:`Placement.controls`): root channels from the target COG
  placement plus the predicted offsets — exact, no rig evaluation.

Rigs without such channels (a face, a mesh with a fixed base) get the plain
pose row: COG-relative joints plus the COG's world position and rotation.
The vertical axis is +Y (every rig reports COG-relative positions Y-up).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rigmap.regression.features import split_features
from rigmap.rigs.base import RigInputError

PLACEMENT_FORMAT = "rigmap.placement/1"
UP = 1  # index of the vertical axis
GROUND_AXES = (0, 2)  # x and z: the ground plane
# probe steps: 1 cm for translations, 0.1 rad for rotations and other channels
TRANSLATE_STEP = 1.0
OTHER_STEP = 0.1
# a channel is "rigid" when the placement-free pose moves less than this (cm, per cm/rad of
# step times the rig's size) and the COG's tilt less than _ROTATION_TOLERANCE
_RELATIVE_TOLERANCE = 1e-5
_ROTATION_TOLERANCE = 1e-5
_MIN_GAIN = 1e-3
_GAIN_AGREEMENT = 1e-3


def heading(cog_rotation: np.ndarray) -> np.ndarray:
    """The COG's turn about the vertical axis, radians in (-pi, pi].

    ``atan2(R02 - R20, R00 + R22)``: turning the whole pose by ``a`` about +Y
    adds exactly ``a`` to it, whatever the COG's tilt (left-multiplying ``R`` by
    a turn rotates the pair ``(R00 + R22, R02 - R20)`` by ``a``).
    """
    R = np.asarray(cog_rotation, dtype=np.float64)
    return np.arctan2(R[..., 0, 2] - R[..., 2, 0], R[..., 0, 0] + R[..., 2, 2])


def turn_matrix(angle: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotations by ``angle`` radians about +Y."""
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((*angle.shape, 3, 3))
    R[..., 0, 0], R[..., 0, 2] = c, s
    R[..., 1, 1] = 1.0
    R[..., 2, 0], R[..., 2, 2] = -s, c
    return R


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


@dataclass(frozen=True)
class Channel:
    """A used control that places the whole character: its column and its gain.

    ``gain``: world cm (translation) or radians of heading (turn) per unit of the control.
    """

    index: int
    name: str
    gain: float

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "name": self.name, "gain": self.gain}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Channel:
        return cls(int(data["index"]), str(data["name"]), float(data["gain"]))


@dataclass(frozen=True)
class Placement:
    """The rig's root channels and the placement-free inputs and targets they allow.

    ``ground``: the channels translating the character along world x and z (both or
    neither); ``turn``: the channel turning it about +Y (only with ``ground``), about
    the pivot ``pivot_rest`` (x, z in cm) plus the ground translation;
    ``turn_range``: the turn control's (lower, upper), into which it is wrapped.
    """

    n_joints: int
    n_controls: int
    ground: tuple[Channel, Channel] | None = None
    turn: Channel | None = None
    pivot_rest: tuple[float, float] = (0.0, 0.0)
    turn_range: tuple[float, float] = (-np.pi, np.pi)
    notes: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if self.turn is not None and self.ground is None:
            raise ValueError("Placement: a turn channel needs the ground channels too")

    # ----------------------------------------------------------------- shapes
    @property
    def pose_width(self) -> int:
        """Width of the pose rows it reads (``inverse_features``): 3J + 3 + 9."""
        return 3 * self.n_joints + 12

    @property
    def input_width(self) -> int:
        """Width of the regressor inputs: the pose row minus the COG's ground position."""
        return self.pose_width - (2 if self.ground is not None else 0)

    @property
    def channels(self) -> list[Channel]:
        found = list(self.ground or ())
        return found + ([self.turn] if self.turn is not None else [])

    def describe(self) -> str:
        if self.ground is None:
            return "no root channels found: inputs keep the COG's world position and rotation"
        names = ", ".join(f"{c.name} (gain {c.gain:g})" for c in self.channels)
        frame = "heading frame" if self.turn is not None else "world orientation"
        return f"root channels solved from the COG placement: {names}; inputs in the {frame}"

    # ----------------------------------------------------------------- inputs
    def _split(self, X_pose: Any, where: str):
        X = np.asarray(X_pose, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.pose_width:
            raise RigInputError(
                f"{where}: expected pose rows of shape (N, {self.pose_width}) (3 x "
                f"{self.n_joints} joints + COG position and rotation), got {X.shape}"
            )
        return split_features(X, self.n_joints)

    def _turns(self, rotation: np.ndarray) -> np.ndarray:
        """Per-row rotation into the frame the regressor sees: the heading, or none."""
        if self.turn is None:
            return np.broadcast_to(np.eye(3), rotation.shape).copy()
        return turn_matrix(heading(rotation))

    def inputs(self, X_pose: Any, where: str = "pose rows") -> np.ndarray:
        """Regressor inputs ``(N, input_width)`` from pose rows ``(N, 3J + 12)``."""
        positions, cog, rotation = self._split(X_pose, where)
        n = len(positions)
        if self.ground is None:
            return np.asarray(X_pose, dtype=np.float64).copy()
        R = self._turns(rotation)
        local = np.einsum("nab,nja->njb", R, positions)  # R^T p for every joint
        tilt = np.einsum("nba,nbc->nac", R, rotation)  # R^T rotation
        return np.concatenate([local.reshape(n, -1), cog[:, UP : UP + 1], tilt.reshape(n, 9)], 1)

    # ----------------------------------------------------------------- targets
    def _check_controls(self, Y: Any, n: int, where: str) -> np.ndarray:
        Y = np.asarray(Y, dtype=np.float64)
        if Y.shape != (n, self.n_controls):
            raise RigInputError(
                f"{where}: expected controls of shape ({n}, {self.n_controls}), got {Y.shape}"
            )
        return Y

    def _controls_and_placement(self, Y: Any, X_pose: Any, where: str):
        """A checked copy of the controls, and the COG position and rotation of each row."""
        positions, cog, rotation = self._split(X_pose, where)
        return self._check_controls(Y, len(positions), where).copy(), cog, rotation

    def targets(self, Y_used: Any, X_pose: Any, where: str = "training rows") -> np.ndarray:
        """Used controls with the root channels replaced by their placement-free offsets."""
        Y, cog, rotation = self._controls_and_placement(Y_used, X_pose, where)
        if self.ground is None:
            return Y
        gx, gz = self.ground
        pivot = np.zeros_like(cog)
        pivot[:, 0] = self.pivot_rest[0] + gx.gain * Y[:, gx.index]
        pivot[:, 2] = self.pivot_rest[1] + gz.gain * Y[:, gz.index]
        pivot[:, UP] = cog[:, UP]
        offset = np.einsum("nba,nb->na", self._turns(rotation), pivot - cog)
        Y[:, gx.index], Y[:, gz.index] = offset[:, 0], offset[:, 2]
        if self.turn is not None:
            turn = self.turn.gain * Y[:, self.turn.index]
            Y[:, self.turn.index] = _wrap(heading(rotation) - turn)
        return Y

    def controls(self, Y_targets: Any, X_pose: Any, where: str = "pose rows") -> np.ndarray:
        """The inverse of :meth:`targets`: root channels from the COG placement."""
        Y, cog, rotation = self._controls_and_placement(Y_targets, X_pose, where)
        if self.ground is None:
            return Y
        gx, gz = self.ground
        if self.turn is not None:
            turn = (heading(rotation) - Y[:, self.turn.index]) / self.turn.gain
            low, high = self.turn_range
            if high - low >= 2.0 * np.pi - 1e-9:  # a full circle: wrap into the range
                turn = low + (turn - low) % (2.0 * np.pi)
            Y[:, self.turn.index] = turn
        offset = np.zeros_like(cog)
        offset[:, 0], offset[:, 2] = Y[:, gx.index], Y[:, gz.index]
        pivot = cog + np.einsum("nab,nb->na", self._turns(rotation), offset)
        Y[:, gx.index] = (pivot[:, 0] - self.pivot_rest[0]) / gx.gain
        Y[:, gz.index] = (pivot[:, 2] - self.pivot_rest[1]) / gz.gain
        return Y

    # ----------------------------------------------------------------- Jacobians
    def jacobians_to_inputs_frame(self, J: Any, X_pose: Any) -> np.ndarray:
        """World-oriented Jacobians ``(N, 3J, C)`` of the COG-relative joints, turned into
        the frame of :meth:`inputs` (where they do not depend on the heading)."""
        return self._turn_jacobians(J, X_pose, inverse=True)

    def jacobians_to_world(self, J: Any, X_pose: Any) -> np.ndarray:
        """The inverse of :meth:`jacobians_to_inputs_frame`."""
        return self._turn_jacobians(J, X_pose, inverse=False)

    def turns_of(self, X_pose: Any) -> np.ndarray:
        """``(N, 3, 3)``: the rotation :meth:`jacobians_to_world` applies to each row's joints."""
        _, _, rotation = self._split(X_pose, "Jacobian poses")
        return self._turns(rotation)

    def _turn_jacobians(self, J: Any, X_pose: Any, inverse: bool) -> np.ndarray:
        _, _, rotation = self._split(X_pose, "Jacobian poses")
        J = np.asarray(J, dtype=np.float64)
        n = len(rotation)
        if J.ndim != 3 or J.shape[:2] != (n, 3 * self.n_joints):
            raise RigInputError(
                f"expected Jacobians of shape ({n}, {3 * self.n_joints}, C), got {J.shape}"
            )
        if self.turn is None:
            return J.copy()
        R = self._turns(rotation)
        blocks = J.reshape(n, self.n_joints, 3, J.shape[2])
        spec = "nba,njbc->njac" if inverse else "nab,njbc->njac"
        return np.einsum(spec, R, blocks).reshape(J.shape)

    # ----------------------------------------------------------------- files
    def to_dict(self) -> dict[str, Any]:
        return {
            "format": PLACEMENT_FORMAT,
            "n_joints": self.n_joints,
            "n_controls": self.n_controls,
            "ground": [c.to_dict() for c in self.ground] if self.ground else None,
            "turn": self.turn.to_dict() if self.turn else None,
            "pivot_rest": list(self.pivot_rest),
            "turn_range": list(self.turn_range),
            "notes": list(self.notes),
            "description": self.describe(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], source: str = "placement") -> Placement:
        if data.get("format") != PLACEMENT_FORMAT:
            raise ValueError(
                f"{source}: expected format {PLACEMENT_FORMAT!r}, got {data.get('format')!r}"
            )
        ground = data.get("ground")
        turn = data.get("turn")
        return cls(
            n_joints=int(data["n_joints"]),
            n_controls=int(data["n_controls"]),
            ground=tuple(Channel.from_dict(c) for c in ground) if ground else None,
            turn=Channel.from_dict(turn) if turn else None,
            pivot_rest=tuple(float(v) for v in data["pivot_rest"]),
            turn_range=tuple(float(v) for v in data["turn_range"]),
            notes=tuple(str(v) for v in data.get("notes", ())),
        )


# --------------------------------------------------------------------------- finding it
def find_placement(rig, probes: Any) -> Placement:
    """Probe the rig as a black box for the channels that place the whole character.

    ``probes``: ``(K, C_used)`` used-control vectors (the rest pose and a few corpus
    frames). Every used control is stepped at every probe; a channel counts only if it
    moves (or turns) the pose rigidly by the same gain at all of them, so a child
    control (a COG offset under the root) is not mistaken for the root. The first such
    channel in control order wins per axis; the others are noted and left to the
    regressor.
    """
    probes = np.atleast_2d(np.asarray(probes, dtype=np.float64))
    used = list(rig.used_controls)
    n_used, n_probes = len(used), len(probes)
    kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
    steps = np.array([TRANSLATE_STEP if k == "translate" else OTHER_STEP for k in kinds])
    base = rig.expand_used(probes)  # (K, C_full)
    stepped = np.repeat(base[:, None, :], n_used + 1, axis=1)
    columns = np.asarray(rig.controls.used_indices)
    stepped[:, np.arange(1, n_used + 1), columns] += steps
    pose = rig.pose(stepped.reshape(-1, base.shape[1]))
    positions = np.asarray(pose.positions, dtype=np.float64).reshape(n_probes, n_used + 1, -1, 3)
    cog = np.asarray(pose.cog, dtype=np.float64).reshape(n_probes, n_used + 1, 3)
    rotation = np.asarray(pose.cog_rotation, dtype=np.float64).reshape(n_probes, n_used + 1, 3, 3)

    angle = heading(rotation)
    R = turn_matrix(angle)
    local = np.einsum("kuba,kujb->kuja", R, positions)
    tilt = np.einsum("kuba,kubc->kuac", R, rotation)
    size = max(float(np.ptp(positions[:, 0].reshape(-1, 3), axis=0).max()), 1.0)
    moved = np.abs(local[:, 1:] - local[:, :1]).max(axis=(2, 3))  # (K, C_used)
    tilted = np.abs(tilt[:, 1:] - tilt[:, :1]).max(axis=(2, 3))
    rigid = (moved <= _RELATIVE_TOLERANCE * size * steps) & (tilted <= _ROTATION_TOLERANCE)
    turned = _wrap(angle[:, 1:] - angle[:, :1]) / steps  # (K, C_used)
    shift = (cog[:, 1:] - cog[:, :1]) / steps[None, :, None]  # (K, C_used, 3)

    def consistent(gains: np.ndarray) -> bool:
        reference = gains[0]
        return abs(reference) >= _MIN_GAIN and bool(
            np.all(np.abs(gains - reference) <= _GAIN_AGREEMENT * abs(reference))
        )

    found: dict[str, list[Channel]] = {"x": [], "z": [], "turn": []}
    for c in range(n_used):
        if not rigid[:, c].all():
            continue
        if np.abs(turned[:, c]).max() <= _ROTATION_TOLERANCE:
            for axis, label in zip(GROUND_AXES, ("x", "z"), strict=True):
                others = [a for a in range(3) if a != axis]
                pure = np.abs(shift[:, c, others]).max() <= _RELATIVE_TOLERANCE * size
                if pure and consistent(shift[:, c, axis]):
                    found[label].append(Channel(c, used[c], float(shift[0, c, axis])))
        elif consistent(turned[:, c]):
            found["turn"].append(Channel(c, used[c], float(turned[0, c])))

    notes = []
    for label, channels in found.items():
        if len(channels) > 1:
            notes.append(
                f"{len(channels)} channels place the character along {label} "
                f"({', '.join(ch.name for ch in channels)}); {channels[0].name} is solved, "
                "the others are regressed"
            )
    if not (found["x"] and found["z"]):
        if found["x"] or found["z"] or found["turn"]:
            notes.append("no pair of ground-plane translations: no root channel is solved")
        return Placement(rig.n_joints, n_used, notes=tuple(notes))
    ground = (found["x"][0], found["z"][0])
    turn = found["turn"][0] if found["turn"] else None
    pivot = _pivot_rest(ground, turn, probes, cog, steps)
    turn_range = (-np.pi, np.pi)
    if turn is not None:
        full = rig.controls.used_indices[turn.index]
        turn_range = (float(rig.controls.lower[full]), float(rig.controls.upper[full]))
    return Placement(rig.n_joints, n_used, ground, turn, pivot, turn_range, tuple(notes))


def _pivot_rest(ground, turn, probes, cog, steps) -> tuple[float, float]:
    """Where the turn channel turns about when the ground channels are zero (x, z in cm).

    Turning by ``a`` about pivot ``p`` maps the COG ``c`` to ``p + T(a)(c - p)``, so
    ``(I - T(a)) p = c' - T(a) c`` gives ``p`` on the ground plane.
    """
    if turn is None:
        return (0.0, 0.0)
    a = turn.gain * steps[turn.index]
    T = turn_matrix(np.array(a))[np.ix_(GROUND_AXES, GROUND_AXES)]
    system = np.eye(2) - T
    before = cog[:, 0][:, GROUND_AXES]
    after = cog[:, 1 + turn.index][:, GROUND_AXES]
    pivots = np.linalg.solve(system[None], (after - before @ T.T)[..., None])[..., 0]
    gx, gz = ground
    rest = pivots - np.stack([gx.gain * probes[:, gx.index], gz.gain * probes[:, gz.index]], 1)
    return (float(rest[:, 0].mean()), float(rest[:, 1].mean()))
