"""Limbs: FK chain + two-bone IK with pole, IK/FK blend, optional foot roll and hock.

One unit covers a biped arm (no foot), a biped leg or a dog's front leg
(reverse-foot roll at the end) and a dog's hind leg (digitigrade: a hock
control between the two-bone IK and the paw). Its controls:

- ``{name}_ik`` (IK hand/foot control, in ``ik_space``), ``{name}_pole`` (pole vector);
- ``{joint}_fk`` for every joint (FK controls, only active when ``ik_fk`` < 1);
- attributes ``{name}.ik_fk`` (1 = IK, 0 = FK), ``{name}.stretch``, ``{name}.twist``,
  and the foot-roll attributes when there is a foot;
- ``{name}_hock`` for a digitigrade leg (rotates the hock about the paw).

The IK/FK blend works like a two-target parent constraint: joint positions and
orientations are interpolated between the FK and IK results.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from rigmap.rigs.engine.builder import EvalContext, RigBuilder
from rigmap.rigs.engine.transforms import Transform, rotation_between
from rigmap.rigs.features.fk_chain import fk_chain
from rigmap.rigs.features.foot_roll import (
    foot_roll_attributes,
    pivots_from_rest,
    relative,
    reverse_foot,
)
from rigmap.rigs.features.two_bone_ik import solve_two_bone_ik

FK_PREFIX = "fk:"


@dataclass(frozen=True)
class FootSpec:
    """Rest world positions (cm) of the foot parts; ``ball``/``toe`` joint names.

    ``ball_joint`` may be None when nothing but the toes hinge at the ball (a dog's
    paw); the ball transform is still written as ``{limb}:ball`` for toes to hang from.
    """

    heel: Sequence[float]
    ball: Sequence[float]
    toe: Sequence[float]
    half_width: float
    toe_joint: str
    ball_joint: str | None = None


@dataclass(frozen=True)
class LimbUsage:
    """Which of the limb's channels the animators key."""

    ik: str = "tx ty tz rx ry rz"
    pole: str = "tx ty tz"
    fk: str = ""
    hock: str = "rx"
    attributes: tuple[str, ...] = ("ik_fk",)
    foot: tuple[str, ...] = ("roll", "bank", "toe_tap")
    # soft range of the IK and pole controls' translation around their rest place (cm)
    ik_range: float = 30.0


@dataclass(frozen=True)
class _LimbRest:
    """The limb's rest geometry (cm, world): what the IK frames are measured against."""

    points: dict[str, np.ndarray]
    upper: str
    mid: str
    hock: str | None
    end: str
    pole: np.ndarray
    l1: float
    l2: float
    rest_normal: np.ndarray
    rest_upper_dir: np.ndarray
    rest_lower_dir: np.ndarray

    @property
    def ik_chain_end(self) -> str:
        """Where the two-bone IK ends: the hock of a digitigrade leg, else the end joint."""
        return self.hock if self.hock is not None else self.end


@dataclass(frozen=True)
class _LimbControls:
    """The IK half's controls and the limb's attributes (``hock``/``roll`` may be None)."""

    ik: object
    pole: object
    ik_fk: object
    stretch: object
    twist: object
    hock: object | None
    roll: object | None


def limb(
    b: RigBuilder,
    name: str,
    *,
    rest: dict[str, Sequence[float]],
    parent: str,
    side_sign: float,
    joints: Sequence[str] | None = None,
    parent_joint: str | None = None,
    ik_space: str = "root",
    pole_distance: float = 40.0,
    group: str | None = None,
    foot: FootSpec | None = None,
    digitigrade: bool = False,
    usage: LimbUsage = LimbUsage(),
) -> None:
    """Add a limb whose ``joints`` are (upper, mid, end) or, digitigrade, (upper, mid, hock, end).

    ``rest`` maps joint names to rest world positions; ``joints`` default to its
    keys in order, ``parent_joint`` to ``parent``, the control ``group`` to the
    limb's ``name``. The pole control is placed ``pole_distance`` cm from the mid
    joint (40 cm by default, our value), in the limb's rest plane on the side it
    bends to, so the rest IK pose equals the rest FK pose exactly. The step
    poses the IK half (:func:`_ik_pose`) and the FK half (:func:`_fk_pose`) and
    blends them by ``ik_fk`` (:func:`_blend`).
    """
    joints = list(rest) if joints is None else list(joints)
    parent_joint = parent if parent_joint is None else parent_joint
    group = name if group is None else group
    expected = 4 if digitigrade else 3
    if len(joints) != expected:
        raise ValueError(f"limb {name!r}: needs {expected} joints, got {list(joints)}")
    points = {j: np.asarray(rest[j], dtype=np.float64) for j in joints}
    _fk_controls(b, joints, points, parent=parent, group=group, foot=foot, usage=usage)
    geometry = _rest_geometry(name, joints, points, pole_distance, digitigrade)
    controls = _ik_controls(b, name, geometry, ik_space, group, digitigrade, foot, usage)
    pivots = None
    if foot is not None:
        pivots = pivots_from_rest(
            points[geometry.end],
            np.asarray(foot.heel, float),
            np.asarray(foot.ball, float),
            np.asarray(foot.toe, float),
            foot.half_width,
            side_sign,
        )
    _declare_joints(b, geometry, parent_joint, foot)
    root_offset = b.offset_to(parent, points[geometry.upper])
    fk_toe_offset = fk_ball_offset = None
    if foot is not None:
        ball_or_end = foot.ball if foot.ball_joint else rest[geometry.end]
        fk_toe_offset = np.asarray(foot.toe, float) - np.asarray(ball_or_end, float)
        fk_ball_offset = np.asarray(foot.ball, float) - points[geometry.end]

    def step(ctx: EvalContext) -> None:
        ik = _ik_pose(ctx, name, geometry, controls, parent, root_offset, pivots, foot, side_sign)
        fk = _fk_pose(ctx, name, joints, geometry.end, foot, fk_ball_offset, fk_toe_offset)
        _blend(ctx, name, fk, ik, controls.ik_fk(ctx), foot)

    b.step(step)
    for j in joints:
        b.set_rest(j, points[j])
    if foot is not None:
        b.set_rest(f"{name}:ball", foot.ball)
        b.set_rest(foot.toe_joint, foot.toe)
        if foot.ball_joint is not None:
            b.set_rest(foot.ball_joint, foot.ball)


def _fk_controls(b, joints, points, *, parent, group, foot, usage) -> None:
    """The FK half: one control per joint (plus the ball when there is one)."""
    fk_joints = list(joints)
    if foot is not None and foot.ball_joint is not None:
        fk_joints.append(foot.ball_joint)
        points[foot.ball_joint] = np.asarray(foot.ball, dtype=np.float64)
    fk_chain(
        b,
        fk_joints,
        parent=parent,
        positions=[points[j] for j in fk_joints],
        group=group,
        used=usage.fk,
        declare_joints=False,
        xform_prefix=FK_PREFIX,
    )


def _rest_geometry(name, joints, points, pole_distance, digitigrade) -> _LimbRest:
    """Pole placement and the rest bone lengths, directions and bend normal."""
    upper, mid = joints[0], joints[1]
    hock = joints[2] if digitigrade else None
    end = joints[-1]
    ik_chain_end = hock if digitigrade else end
    bend = points[mid] - points[upper]
    axis = points[ik_chain_end] - points[upper]
    bend = bend - (bend @ axis) / (axis @ axis) * axis
    if np.linalg.norm(bend) < 1e-3:
        raise ValueError(f"limb {name!r}: the rest pose must bend at {mid!r} to define the pole")
    pole = points[mid] + pole_distance * bend / np.linalg.norm(bend)
    rest_axis = points[ik_chain_end] - points[upper]
    rest_side = pole - points[upper]
    rest_normal = np.cross(
        rest_axis, rest_side - rest_side @ rest_axis / (rest_axis @ rest_axis) * rest_axis
    )
    if np.linalg.norm(rest_normal) < 1e-6:
        raise ValueError(f"limb {name!r}: pole lies on the limb's axis at rest")
    return _LimbRest(
        points=points,
        upper=upper,
        mid=mid,
        hock=hock,
        end=end,
        pole=pole,
        l1=float(np.linalg.norm(points[mid] - points[upper])),
        l2=float(np.linalg.norm(points[ik_chain_end] - points[mid])),
        rest_normal=rest_normal,
        rest_upper_dir=points[mid] - points[upper],
        rest_lower_dir=points[ik_chain_end] - points[mid],
    )


def _ik_controls(b, name, geometry, ik_space, group, digitigrade, foot, usage) -> _LimbControls:
    """The IK and pole controls, the ik_fk/stretch/twist attributes, hock and foot roll."""
    points = geometry.points
    ik_ctrl, pole_ctrl = (
        b.transform_control(
            f"{name}_{kind}",
            parent=ik_space,
            offset=b.offset_to(ik_space, where),
            group=group,
            used=used,
            translate_range=usage.ik_range,
            add_step=True,
        )
        for kind, where, used in (
            ("ik", points[geometry.end], usage.ik),
            ("pole", geometry.pole, usage.pole),
        )
    )
    ik_fk, stretch, twist = (
        b.attribute(
            f"{name}.{attribute}",
            default=default,
            lower=lower,
            upper=upper,
            used=attribute in usage.attributes,
            group=group,
        )
        for attribute, default, lower, upper in (
            ("ik_fk", 1.0, 0.0, 1.0),
            ("stretch", 0.0, 0.0, 1.0),
            ("twist", 0.0, -np.pi, np.pi),
        )
    )
    hock_ctrl = None
    if digitigrade:
        # pivots at the paw; rotating it swings the hock (and so the whole leg) about the paw
        hock_ctrl = b.transform_control(
            f"{name}_hock",
            parent=f"{name}_ik",
            offset=(0.0, 0.0, 0.0),
            group=group,
            used=usage.hock,
            rotate_range=np.pi / 2,
            add_step=False,
        )
    roll = None if foot is None else foot_roll_attributes(b, name, group=group, used=usage.foot)
    return _LimbControls(ik_ctrl, pole_ctrl, ik_fk, stretch, twist, hock_ctrl, roll)


def _declare_joints(b, geometry: _LimbRest, parent_joint: str, foot: FootSpec | None) -> None:
    b.joint(geometry.upper, parent_joint)
    b.joint(geometry.mid, geometry.upper)
    if geometry.hock is not None:
        b.joint(geometry.hock, geometry.mid)
    b.joint(geometry.end, geometry.hock or geometry.mid)
    if foot is not None:
        if foot.ball_joint is not None:
            b.joint(foot.ball_joint, geometry.end)
        b.joint(foot.toe_joint, foot.ball_joint or geometry.end)


def _ik_pose(ctx, name, geometry, controls, parent, root_offset, pivots, foot, side_sign) -> dict:
    """World transforms of the IK half: the two-bone solve to the (rolled) foot or hock."""
    points, end = geometry.points, geometry.end
    ik_world = ctx.xf[controls.ik.name]
    if pivots is not None:
        rolled = reverse_foot(ctx, pivots, controls.roll, side_sign)
        end_world = ik_world.compose(rolled.ankle)
    else:
        end_world = ik_world
    if controls.hock is not None:
        hock_offset = points[geometry.hock] - points[end]
        hock_pivot = end_world.compose(controls.hock.local(ctx))
        hock_world = Transform(hock_pivot.R, hock_pivot.apply(ctx.const(hock_offset)))
        target = hock_world.t
    else:
        target = end_world.t
    root = ctx.xf[parent].apply(ctx.const(root_offset))
    solution = solve_two_bone_ik(
        root,
        target,
        ctx.xf[controls.pole.name].t,
        geometry.l1,
        geometry.l2,
        stretch=controls.stretch(ctx),
        twist=controls.twist(ctx),
    )
    normal0 = ctx.const(geometry.rest_normal).expand_as(root)
    R_upper = rotation_between(
        ctx.const(geometry.rest_upper_dir).expand_as(root),
        normal0,
        solution.mid - root,
        solution.normal,
    )
    R_lower = rotation_between(
        ctx.const(geometry.rest_lower_dir).expand_as(root),
        normal0,
        solution.end - solution.mid,
        solution.normal,
    )
    ik = {
        geometry.upper: Transform(R_upper, root),
        geometry.mid: Transform(R_lower, solution.mid),
    }
    if controls.hock is not None:
        ik[geometry.hock] = Transform(hock_world.R, solution.end)
        # the paw keeps its place relative to the (possibly unreachable) hock
        ik[end] = Transform(end_world.R, solution.end + (end_world.t - hock_world.t))
    else:
        ik[end] = Transform(end_world.R, solution.end)
    if pivots is not None:
        ik_end = ik[end]
        ik[f"{name}:ball"] = ik_end.compose(relative(rolled.ankle, rolled.ball))
        ik[foot.toe_joint] = ik_end.compose(relative(rolled.ankle, rolled.toe))
    return ik


def _fk_pose(ctx, name, joints, end, foot, fk_ball_offset, fk_toe_offset) -> dict:
    """World transforms of the FK half, with the ball and toe the foot hangs from them."""
    fk = {j: ctx.xf[FK_PREFIX + j] for j in joints}
    if foot is not None:
        if foot.ball_joint is not None:
            fk[f"{name}:ball"] = ctx.xf[FK_PREFIX + foot.ball_joint]
            toe_parent = fk[f"{name}:ball"]
        else:
            fk[f"{name}:ball"] = fk[end].compose(
                Transform(
                    torch.eye(3, dtype=ctx.dtype).expand(ctx.n, 3, 3),
                    ctx.const(fk_ball_offset).expand(ctx.n, 3),
                )
            )
            toe_parent = fk[end]
        fk[foot.toe_joint] = Transform(toe_parent.R, toe_parent.apply(ctx.const(fk_toe_offset)))
    return fk


def _blend(ctx, name: str, fk: dict, ik: dict, w, foot: FootSpec | None) -> None:
    """Write the IK/FK blend (``w`` = 1: IK) of every IK transform into the context."""
    for key, ik_xf in ik.items():
        ctx.xf[key] = _lerp(fk[key], ik_xf, w)
    if foot is not None and foot.ball_joint is not None:
        ctx.xf[foot.ball_joint] = ctx.xf[f"{name}:ball"]


def _lerp(a: Transform, b: Transform, w: torch.Tensor) -> Transform:
    """Blend two transforms (positions and linear parts); exact at w = 0 and 1."""
    return Transform(
        a.R + w[:, None, None] * (b.R - a.R),
        a.t + w[:, None] * (b.t - a.t),
    )
