"""Forward-kinematics chains: one rotate/translate/scale control per joint.

Each joint's world transform is ``parent ∘ T(offset + t) ∘ R_layer ∘ R(r) ∘ S(s)``
where the optional layer adds chain-wide curl/wave (see chain_attributes).
Rest orientations are world-aligned, so a joint's rest offset is a world vector (cm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from rigmap.rigs.engine.builder import EvalContext, RigBuilder, TransformControl
from rigmap.rigs.engine.transforms import Transform
from rigmap.rigs.features.chain_attributes import ChainAttributes

#: a layered chain's rotations computed for all its joints at once (``ChainAttributes.rotations``
#: and one batched product), equal to the joint-by-joint ones to the last bit (ours; off: the
#: joint-by-joint code, kept for ``benchmarks/refine.py``'s same-run comparison)
BATCHED_LAYERS = True


def fk_chain(
    b: RigBuilder,
    joints: Sequence[str],
    *,
    parent: str,
    positions: Sequence[Sequence[float]],
    group: str,
    used: str = "rx ry rz",
    rotation_orders: str | Sequence[str] = "xyz",
    rotate_range: float | dict = np.pi,
    layer: ChainAttributes | None = None,
    joint_parent: str | None = None,
    control_suffix: str = "_fk",
    declare_joints: bool = True,
    xform_prefix: str = "",
    tip: Sequence[float] | None = None,
    tip_name: str | None = None,
) -> list[TransformControl]:
    """A chain of FK controls whose world transforms are the joints' transforms.

    ``positions`` are the joints' rest world positions (cm). ``parent`` is the
    transform the chain hangs from; ``joint_parent`` the joint recorded as the
    first joint's parent (defaults to ``parent``). With ``xform_prefix`` the
    chain writes ``prefix + joint`` transforms and declares no joints (a limb's
    FK half, blended with its IK half later). ``tip`` adds an end joint
    (``tip_name``, default ``{last}_tip``) rigidly carried by the last control, so
    the last control's rotation shows in joint positions.
    """
    if len(positions) != len(joints):
        raise ValueError(
            f"fk_chain {joints[0]}: {len(joints)} joints but {len(positions)} positions"
        )
    orders = (
        [rotation_orders] * len(joints) if isinstance(rotation_orders, str) else rotation_orders
    )
    controls: list[TransformControl] = []
    previous = parent
    for joint, position, order in zip(joints, positions, orders, strict=True):
        ctrl = b.transform_control(
            f"{joint}{control_suffix}",
            parent=previous,
            offset=b.offset_to(previous, position),
            group=group,
            used=used,
            rotation_order=order,
            rotate_range=rotate_range,
            add_step=False,
        )
        controls.append(ctrl)
        b.rest[xform_prefix + joint] = b.rest[ctrl.name]
        if declare_joints:
            first_parent = joint_parent if joint_parent is not None else parent
            b.joint(
                joint, first_parent if previous == parent else previous.removeprefix(xform_prefix)
            )
        previous = xform_prefix + joint
    tip_offset = None
    if tip is not None:
        tip_name = tip_name or f"{joints[-1]}_tip"
        tip_offset = b.offset_to(previous, tip)
        tip_parent = joints[-1] if declare_joints else (joint_parent or parent)
        b.joint(tip_name, tip_parent)
        b.set_rest(tip_name, tip)

    def step(ctx: EvalContext) -> None:
        world = ctx.xf[parent]
        locals_ = _chain_locals(ctx, controls, layer)
        for joint, ctrl, local in zip(joints, controls, locals_, strict=True):
            world = world.compose(local)
            ctx.xf[xform_prefix + joint] = world
            ctx.xf[ctrl.name] = world
        if tip_offset is not None:
            ctx.xf[tip_name] = Transform(world.R, world.apply(ctx.const(tip_offset)))

    b.step(step)
    return controls


def _chain_locals(
    ctx: EvalContext, controls: list[TransformControl], layer: ChainAttributes | None
) -> list[Transform]:
    """Each control's local transform, turned by the chain's layered rotation if it has one."""
    locals_ = [ctrl.local(ctx) for ctrl in controls]
    if layer is None:
        return locals_
    count = len(controls)
    if BATCHED_LAYERS:  # every joint's R_layer ∘ R(r) ∘ S(s) at once
        layered = layer.rotations(ctx, count) @ torch.stack([lc.R for lc in locals_], dim=1)
        return [Transform(layered[:, i], lc.t) for i, lc in enumerate(locals_)]
    return [Transform(layer.rotation(ctx, i, count) @ lc.R, lc.t) for i, lc in enumerate(locals_)]


def fk_joint(
    b: RigBuilder,
    joint: str,
    *,
    parent: str,
    position: Sequence[float],
    group: str,
    used: str,
    rotate_range: float | dict,
) -> TransformControl:
    """One joint turned by its own control ``<joint>_ctrl`` (a jaw, a clavicle, a scapula)."""
    (control,) = fk_chain(
        b,
        [joint],
        parent=parent,
        positions=[position],
        group=group,
        used=used,
        rotate_range=rotate_range,
        control_suffix="_ctrl",
    )
    return control
