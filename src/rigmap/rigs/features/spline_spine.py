"""A spline spine between a hips control and a chest control.

The spine joints ride a cubic Bézier whose end tangents follow the hips and
chest controls' orientations, so tilting the chest bends the back smoothly; a
mid control pulls the curve's middle through itself, twist is spread along the
chain by blending the two end orientations, and ``stretch`` (1 = free, 0 =
preserve length) decides whether the spine may lengthen. Per-joint tweak
controls offset individual vertebrae, as in Rigify's spine.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from rigmap.rigs.engine.builder import EvalContext, RigBuilder, TransformControl
from rigmap.rigs.engine.transforms import Transform, blend_rotations, orthonormalize


def spline_spine(
    b: RigBuilder,
    joints: Sequence[str],
    *,
    hips: str,
    chest: str,
    mid: TransformControl,
    parent_joint: str | None,
    group: str,
    tweak_used: str = "",
) -> None:
    """Write ``joints`` (first at the hips control, last at the chest control).

    The hips, chest and mid controls must exist (with world steps) already; the
    joints' rest positions are placed evenly on the straight rest curve. The mid
    control's own translation (in its parent's space) pushes the curve's middle.
    """
    start, end = b.rest[hips], b.rest[chest]
    rest_length = float(np.linalg.norm(end - start))
    direction = (end - start) / rest_length
    count = len(joints)
    params = np.linspace(0.0, 1.0, count)
    stretch = b.attribute(
        f"{joints[0]}_spine.stretch", default=1.0, lower=0.0, upper=1.0, used=False, group=group
    )
    tweaks = []
    for i, joint in enumerate(joints):
        position = start + params[i] * (end - start)
        b.joint(joint, parent_joint if i == 0 else joints[i - 1])
        b.set_rest(joint, position)
        if 0 < i < count - 1:
            tweaks.append(
                b.transform_control(
                    f"{joint}_tweak",
                    parent=joint,
                    offset=(0, 0, 0),
                    group=group,
                    used=tweak_used,
                    add_step=False,
                )
            )
    weights = params[1:-1]
    # how far the Bézier's middle moves per unit of control-point shift (8/6)
    mid_gain = 4.0 / 3.0

    def step(ctx: EvalContext) -> None:
        H, C = ctx.xf[hips], ctx.xf[chest]
        handle = ctx.const(direction * rest_length / 3.0)
        p0, p3 = H.t, C.t
        mid_space = ctx.xf[mid.parent]
        pull = ctx.xf[mid.name].t - mid_space.apply(ctx.const(mid.rest_offset))
        p1 = p0 + H.rotate(handle) + mid_gain * pull
        p2 = p3 - C.rotate(handle) + mid_gain * pull
        t = ctx.const(params)[None, :, None]
        curve = (
            (1 - t) ** 3 * p0[:, None]
            + 3 * (1 - t) ** 2 * t * p1[:, None]
            + 3 * (1 - t) * t**2 * p2[:, None]
            + t**3 * p3[:, None]
        )  # (N, count, 3)
        # preserve length (stretch=0) by scaling the chain about its start
        length = torch.linalg.norm(curve[:, 1:] - curve[:, :-1], dim=-1).sum(-1)
        keep = (rest_length / length.clamp_min(1e-6)) ** (1.0 - stretch(ctx).clamp(0, 1))
        curve = p0[:, None] + (curve - p0[:, None]) * keep[:, None, None]

        RH, RC = orthonormalize(H.R), orthonormalize(C.R)
        ctx.xf[joints[0]] = Transform(H.R, curve[:, 0])
        for i, (joint, tweak) in enumerate(zip(joints[1:-1], tweaks, strict=True), start=1):
            frame = Transform(
                blend_rotations(RH, RC, torch.full_like(length, float(weights[i - 1]))),
                curve[:, i],
            )
            ctx.xf[joint] = frame.compose(tweak.local(ctx))
        ctx.xf[joints[-1]] = Transform(C.R, curve[:, -1])

    b.step(step)
