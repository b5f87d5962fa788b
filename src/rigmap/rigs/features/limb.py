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


def limb(
    b: RigBuilder,
    name: str,
    *,
    joints: Sequence[str],
    rest: dict[str, Sequence[float]],
    parent: str,
    parent_joint: str,
    ik_space: str,
    pole_distance: float,
    group: str,
    side_sign: float,
    foot: FootSpec | None = None,
    digitigrade: bool = False,
    usage: LimbUsage = LimbUsage(),
) -> None:
    """Add a limb whose ``joints`` are (upper, mid, end) or, digitigrade, (upper, mid, hock, end).

    ``rest`` maps joint names to rest world positions. The pole control is
    placed ``pole_distance`` cm from the mid joint, in the limb's rest plane on the
    side it bends to, so the rest IK pose equals the rest FK pose exactly.
    """
    expected = 4 if digitigrade else 3
    if len(joints) != expected:
        raise ValueError(f"limb {name!r}: needs {expected} joints, got {list(joints)}")
    points = {j: np.asarray(rest[j], dtype=np.float64) for j in joints}
    upper, mid = joints[0], joints[1]
    hock = joints[2] if digitigrade else None
    end = joints[-1]
    ik_chain_end = hock if digitigrade else end  # where the two-bone IK ends

    # --- FK half: one control per joint (plus the ball when there is one) ---
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

    bend = points[mid] - points[upper]
    axis = points[ik_chain_end] - points[upper]
    bend = bend - (bend @ axis) / (axis @ axis) * axis
    if np.linalg.norm(bend) < 1e-3:
        raise ValueError(f"limb {name!r}: the rest pose must bend at {mid!r} to define the pole")
    pole = points[mid] + pole_distance * bend / np.linalg.norm(bend)

    # --- IK half ---
    ik_ctrl = b.transform_control(
        f"{name}_ik",
        parent=ik_space,
        offset=b.offset_to(ik_space, points[end]),
        group=group,
        used=usage.ik,
        translate_range=usage.ik_range,
        add_step=True,
    )
    pole_ctrl = b.transform_control(
        f"{name}_pole",
        parent=ik_space,
        offset=b.offset_to(ik_space, pole),
        group=group,
        used=usage.pole,
        translate_range=usage.ik_range,
        add_step=True,
    )
    ik_fk = b.attribute(
        f"{name}.ik_fk",
        default=1.0,
        lower=0.0,
        upper=1.0,
        used="ik_fk" in usage.attributes,
        group=group,
    )
    stretch = b.attribute(
        f"{name}.stretch",
        default=0.0,
        lower=0.0,
        upper=1.0,
        used="stretch" in usage.attributes,
        group=group,
    )
    twist = b.attribute(
        f"{name}.twist",
        default=0.0,
        lower=-np.pi,
        upper=np.pi,
        used="twist" in usage.attributes,
        group=group,
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
        hock_offset = points[hock] - points[end]
    roll_attrs = pivots = None
    if foot is not None:
        roll_attrs = foot_roll_attributes(b, name, group=group, used=usage.foot)
        pivots = pivots_from_rest(
            points[end],
            np.asarray(foot.heel, float),
            np.asarray(foot.ball, float),
            np.asarray(foot.toe, float),
            foot.half_width,
            side_sign,
        )

    # rest geometry the IK frames are measured against
    l1 = float(np.linalg.norm(points[mid] - points[upper]))
    l2 = float(np.linalg.norm(points[ik_chain_end] - points[mid]))
    rest_axis = points[ik_chain_end] - points[upper]
    rest_side = pole - points[upper]
    rest_normal = np.cross(
        rest_axis, rest_side - rest_side @ rest_axis / (rest_axis @ rest_axis) * rest_axis
    )
    if np.linalg.norm(rest_normal) < 1e-6:
        raise ValueError(f"limb {name!r}: pole lies on the limb's axis at rest")
    root_offset = b.offset_to(parent, points[upper])
    rest_upper_dir = points[mid] - points[upper]
    rest_lower_dir = points[ik_chain_end] - points[mid]

    toe_joint = foot.toe_joint if foot is not None else None
    ball_joint = foot.ball_joint if foot is not None else None
    b.joint(upper, parent_joint)
    b.joint(mid, upper)
    if hock is not None:
        b.joint(hock, mid)
    b.joint(end, hock or mid)
    if ball_joint is not None:
        b.joint(ball_joint, end)
    if toe_joint is not None:
        b.joint(toe_joint, ball_joint or end)
    fk_toe_offset = (
        np.asarray(foot.toe, float) - np.asarray(foot.ball if ball_joint else rest[end], float)
        if foot is not None
        else None
    )
    fk_ball_offset = np.asarray(foot.ball, float) - points[end] if foot is not None else None

    def step(ctx: EvalContext) -> None:
        ik_world = ctx.xf[ik_ctrl.name]
        if pivots is not None:
            rolled = reverse_foot(ctx, pivots, roll_attrs, side_sign)
            end_world = ik_world.compose(rolled.ankle)
        else:
            end_world = ik_world
        if hock_ctrl is not None:
            hock_pivot = end_world.compose(hock_ctrl.local(ctx))
            hock_world = Transform(hock_pivot.R, hock_pivot.apply(ctx.const(hock_offset)))
            target = hock_world.t
        else:
            target = end_world.t
        root = ctx.xf[parent].apply(ctx.const(root_offset))
        solution = solve_two_bone_ik(
            root,
            target,
            ctx.xf[pole_ctrl.name].t,
            l1,
            l2,
            stretch=stretch(ctx),
            twist=twist(ctx),
        )
        normal0 = ctx.const(rest_normal).expand_as(root)
        R_upper = rotation_between(
            ctx.const(rest_upper_dir).expand_as(root), normal0, solution.mid - root, solution.normal
        )
        R_lower = rotation_between(
            ctx.const(rest_lower_dir).expand_as(root),
            normal0,
            solution.end - solution.mid,
            solution.normal,
        )
        ik = {
            upper: Transform(R_upper, root),
            mid: Transform(R_lower, solution.mid),
        }
        if hock_ctrl is not None:
            ik[hock] = Transform(hock_world.R, solution.end)
            # the paw keeps its place relative to the (possibly unreachable) hock
            ik[end] = Transform(end_world.R, solution.end + (end_world.t - hock_world.t))
        else:
            ik[end] = Transform(end_world.R, solution.end)
        if pivots is not None:
            ik_end = ik[end]
            ball_local = relative(rolled.ankle, rolled.ball)
            ik[f"{name}:ball"] = ik_end.compose(ball_local)
            ik[toe_joint] = ik_end.compose(relative(rolled.ankle, rolled.toe))

        fk = {j: ctx.xf[FK_PREFIX + j] for j in joints}
        if pivots is not None:
            if ball_joint is not None:
                fk[f"{name}:ball"] = ctx.xf[FK_PREFIX + ball_joint]
                toe_parent = fk[f"{name}:ball"]
            else:
                fk[f"{name}:ball"] = fk[end].compose(
                    Transform(
                        torch.eye(3, dtype=ctx.dtype).expand(ctx.n, 3, 3),
                        ctx.const(fk_ball_offset).expand(ctx.n, 3),
                    )
                )
                toe_parent = fk[end]
            fk[toe_joint] = Transform(toe_parent.R, toe_parent.apply(ctx.const(fk_toe_offset)))

        w = ik_fk(ctx)
        for key, ik_xf in ik.items():
            blended = _lerp(fk[key], ik_xf, w)
            ctx.xf[key] = blended
        if ball_joint is not None:
            ctx.xf[ball_joint] = ctx.xf[f"{name}:ball"]

    b.step(step)
    for j in joints:
        b.set_rest(j, points[j])
    if foot is not None:
        b.set_rest(f"{name}:ball", foot.ball)
        b.set_rest(toe_joint, foot.toe)
        if ball_joint is not None:
            b.set_rest(ball_joint, foot.ball)


def _lerp(a: Transform, b: Transform, w: torch.Tensor) -> Transform:
    """Blend two transforms (positions and linear parts); exact at w = 0 and 1."""
    return Transform(
        a.R + w[:, None, None] * (b.R - a.R),
        a.t + w[:, None] * (b.t - a.t),
    )
