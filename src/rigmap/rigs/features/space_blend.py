"""Parent-space blend: a control that follows its parent's orientation or the world's.

Heads usually carry a ``follow`` attribute: at 1 the head turns with the
neck, at 0 it keeps its orientation in world (placement) space while the body
moves under it. The control always stays attached at its pivot.
"""

from __future__ import annotations

from collections.abc import Sequence

from rigmap.rigs.engine.builder import EvalContext, RigBuilder, TransformControl
from rigmap.rigs.engine.transforms import Transform, blend_rotations, orthonormalize


def space_blend_control(
    b: RigBuilder,
    name: str,
    *,
    parent: str,
    world_space: str,
    position: Sequence[float],
    group: str,
    used: str,
    follow_used: bool = True,
) -> TransformControl:
    """A control at ``position`` whose orientation space blends ``parent`` ↔ ``world_space``."""
    pivot = b.offset_to(parent, position)
    follow = b.attribute(
        f"{name}.follow", default=1.0, lower=0.0, upper=1.0, used=follow_used, group=group
    )
    ctrl = b.transform_control(
        name, parent=None, offset=(0, 0, 0), group=group, used=used, add_step=False
    )
    b.set_rest(name, position)

    def step(ctx: EvalContext) -> None:
        host = ctx.xf[parent]
        space_R = blend_rotations(
            orthonormalize(ctx.xf[world_space].R), orthonormalize(host.R), follow(ctx)
        )
        space = Transform(space_R, host.apply(ctx.const(pivot)))
        ctx.xf[name] = space.compose(ctrl.local(ctx))

    b.step(step)
    return ctrl
