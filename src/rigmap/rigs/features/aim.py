"""Aim constraints: a joint (an eye) turns to look at a target control.

The eye's end joint (pupil) is what moves in joint space, so the aim shows up
in the joint positions the inverse mapping sees.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rigmap.rigs.engine.builder import EvalContext, RigBuilder
from rigmap.rigs.engine.transforms import Transform, frame_from_axes


def aim_joint(
    b: RigBuilder,
    joint: str,
    end_joint: str,
    *,
    parent: str,
    target: str,
    position: Sequence[float],
    end_position: Sequence[float],
    up: Sequence[float] = (0.0, 1.0, 0.0),
) -> None:
    """``joint`` sits on ``parent`` at ``position`` and aims its end at ``target``."""
    offset = b.offset_to(parent, position)
    rest_forward = b.rest[target] - np.asarray(position, float)
    end_offset = np.asarray(end_position, float) - np.asarray(position, float)
    up_axis = np.asarray(up, float)
    b.joint(joint, parent)
    b.joint(end_joint, joint)
    b.set_rest(joint, position)
    b.set_rest(end_joint, end_position)

    def step(ctx: EvalContext) -> None:
        host = ctx.xf[parent]
        eye = host.apply(ctx.const(offset))
        up_now = host.rotate(ctx.const(up_axis))
        rest_frame = frame_from_axes(
            ctx.const(rest_forward).expand_as(eye), ctx.const(up_axis).expand_as(eye)
        )
        R = frame_from_axes(ctx.xf[target].t - eye, up_now) @ rest_frame.transpose(-1, -2)
        ctx.xf[joint] = Transform(R, eye)
        ctx.xf[end_joint] = Transform(R, eye + (R @ ctx.const(end_offset)[:, None])[..., 0])

    b.step(step)
