"""Reverse-foot roll: heel, ball and toe pivots driven piecewise by one ``roll``.

As ``roll`` sweeps from negative to positive the foot first rocks back on the
heel (roll < 0), then peels off the ground around the ball (0 < roll <
``ball_break``), then rises onto the toe tip (roll > ``ball_break``). ``bank``
rocks it sideways about the inner or outer edge, ``heel_twist``/``toe_twist``
swivel about the heel or toe, ``toe_tap`` lifts the toes about the ball.

Everything here is in the IK foot control's local space (rigid: the control's
own scale is applied by the caller), so relative transforms are cheap to invert.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from rigmap.rigs.engine.builder import Attribute, EvalContext, RigBuilder
from rigmap.rigs.engine.transforms import Transform, axis_rotation, rotation_product


@dataclass(frozen=True)
class FootPivots:
    """Rest points relative to the IK foot control's pivot (cm, world-aligned).

    The foot points along +z (forward), +x is the character's left; ``inner``
    and ``outer`` are the sole's side edges used for banking.
    """

    ankle: tuple[float, float, float]
    heel: tuple[float, float, float]
    ball: tuple[float, float, float]
    toe: tuple[float, float, float]
    inner: tuple[float, float, float]
    outer: tuple[float, float, float]


@dataclass
class FootRollAttributes:
    roll: Attribute
    ball_break: Attribute
    bank: Attribute
    heel_twist: Attribute
    toe_twist: Attribute
    toe_tap: Attribute


def foot_roll_attributes(
    b: RigBuilder, prefix: str, *, group: str, used: tuple[str, ...]
) -> FootRollAttributes:
    """``{prefix}.roll`` and friends, in radians; ``ball_break`` defaults to 0.6 rad."""

    def attr(name, default, lower, upper):
        return b.attribute(
            f"{prefix}.{name}",
            default=default,
            lower=lower,
            upper=upper,
            used=name in used,
            group=group,
        )

    return FootRollAttributes(
        roll=attr("roll", 0.0, -0.8, 1.6),
        ball_break=attr("ball_break", 0.6, 0.1, 1.2),
        bank=attr("bank", 0.0, -0.6, 0.6),
        heel_twist=attr("heel_twist", 0.0, -0.8, 0.8),
        toe_twist=attr("toe_twist", 0.0, -0.8, 0.8),
        toe_tap=attr("toe_tap", 0.0, -0.8, 0.8),
    )


@dataclass
class ReverseFoot:
    """Local transforms (in the foot control's space) of the rolled foot parts."""

    ankle: Transform  # where the leg's IK must end, and the foot's orientation
    ball: Transform  # the ball joint (toes hinge here)
    toe: Transform  # the toe tip
    heel: Transform  # the heel contact point


def reverse_foot(
    ctx: EvalContext,
    pivots: FootPivots,
    attrs: FootRollAttributes,
    side_sign: float = 1.0,
) -> ReverseFoot:
    """Evaluate the pivot hierarchy ``heel → toe → bank → ball → ankle``.

    ``side_sign`` is +1 for a left foot and -1 for a right one, so positive
    bank always rocks onto the inner edge.
    """
    p = {name: ctx.const(getattr(pivots, name)) for name in FootPivots.__dataclass_fields__}
    roll = attrs.roll(ctx)
    ball_break = attrs.ball_break(ctx)
    heel_roll = torch.clamp(roll, max=0.0)
    ball_roll = torch.minimum(torch.clamp(roll, min=0.0), ball_break)
    toe_roll = torch.clamp(roll - ball_break, min=0.0)

    heel = Transform.pivot(
        rotation_product([(heel_roll, "x"), (attrs.heel_twist(ctx), "y")]), p["heel"]
    )
    toe = heel.compose(
        Transform.pivot(rotation_product([(toe_roll, "x"), (attrs.toe_twist(ctx), "y")]), p["toe"])
    )
    bank = attrs.bank(ctx)
    # positive bank rocks onto the inner edge (the outer one lifts), negative onto the outer
    edge = torch.where(
        (bank >= 0)[:, None], p["inner"].expand(ctx.n, 3), p["outer"].expand(ctx.n, 3)
    )
    banked = toe.compose(Transform.pivot(axis_rotation(bank * side_sign, "z"), edge))
    ball_pivot = banked.compose(Transform.pivot(axis_rotation(ball_roll, "x"), p["ball"]))
    tapped = banked.compose(Transform.pivot(axis_rotation(-attrs.toe_tap(ctx), "x"), p["ball"]))

    def placed(frame: Transform, point: torch.Tensor) -> Transform:
        return Transform(frame.R, frame.apply(point))

    return ReverseFoot(
        ankle=placed(ball_pivot, p["ankle"]),
        ball=placed(tapped, p["ball"]),
        toe=placed(tapped, p["toe"]),
        heel=placed(heel, p["heel"]),
    )


def relative(parent: Transform, child: Transform) -> Transform:
    """``parent⁻¹ ∘ child`` for rigid ``parent`` (rotation part orthonormal)."""
    Rt = parent.R.transpose(-1, -2)
    return Transform(Rt @ child.R, (Rt @ (child.t - parent.t)[..., None])[..., 0])


def pivots_from_rest(
    ankle: np.ndarray,
    heel: np.ndarray,
    ball: np.ndarray,
    toe: np.ndarray,
    half_width: float,
    side_sign: float,
) -> FootPivots:
    """Foot pivots relative to the ankle (the control sits at the ankle at rest).

    ``side_sign`` is +1 for a left foot (its inner edge is towards -x), -1 for a right one.
    """

    def rel(point):
        return tuple(float(v) for v in np.asarray(point, dtype=float) - ankle)

    ball_rel = np.asarray(ball, dtype=float) - ankle
    return FootPivots(
        ankle=(0.0, 0.0, 0.0),
        heel=rel(heel),
        ball=rel(ball),
        toe=rel(toe),
        inner=(-half_width * side_sign, float(ball_rel[1]), float(ball_rel[2])),
        outer=(half_width * side_sign, float(ball_rel[1]), float(ball_rel[2])),
    )
