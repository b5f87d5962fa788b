"""Fixed joints: end sites rigidly carried by a transform (head top, snout tip)."""

from __future__ import annotations

from collections.abc import Sequence

from rigmap.rigs.engine.builder import EvalContext, RigBuilder
from rigmap.rigs.engine.transforms import Transform


def fixed_joint(b: RigBuilder, name: str, *, parent: str, position: Sequence[float]) -> None:
    """Declare joint ``name`` under ``parent`` at rest ``position`` (cm) and carry it rigidly."""
    b.joint(name, parent)
    b.set_rest(name, position)
    offset = b.offset_to(parent, position)

    def step(ctx: EvalContext) -> None:
        host = ctx.xf[parent]
        ctx.xf[name] = Transform(host.R, host.apply(ctx.const(offset)))

    b.step(step)
