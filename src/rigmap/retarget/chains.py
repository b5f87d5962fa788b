"""FK controls by aiming: each control turns so its child lands on the child's target.

This is the aim constraint of a retarget script, walked down a chain: the
parent's current world frame is known, the control's pivot follows from it,
and the control gets the rotation (in the parent's frame, in its own
rotation order, restricted to the channels the animators key) that points
its rest child offset at the child's target. Twist about the bone cannot be
seen in joint positions, so a three-channel control gets the smallest
rotation (no added twist).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rigmap.retarget.euler import matrix_to_euler
from rigmap.retarget.orient import angle_about, rotate_back, rotation_between, two_axis_aim
from rigmap.retarget.scene import ScriptScene, WorldTransform


def aim_angles(d0: np.ndarray, d1: np.ndarray, axes: str, order: str) -> np.ndarray:
    """``(N, 3)`` Euler angles turning local direction ``d0`` towards ``d1`` about ``axes``.

    ``axes`` are the rotation channels the control exposes (``"xyz"``, two of
    them, one, or none); ``order`` is its rotation order.
    """
    n = len(d1)
    angles = np.zeros((n, 3))
    if len(axes) == 3:
        return matrix_to_euler(rotation_between(d0, d1), order)
    if len(axes) == 2:
        inner, outer = sorted(axes, key=order.index)
        inner_angle, outer_angle = two_axis_aim(d0, d1, inner, outer)
        angles[:, "xyz".index(inner)] = inner_angle
        angles[:, "xyz".index(outer)] = outer_angle
    elif len(axes) == 1:
        angles[:, "xyz".index(axes)] = angle_about(d0, d1, axes)
    return angles


def aim_chain(
    scene: ScriptScene,
    parent: WorldTransform,
    parent_name: str,
    controls: Sequence[str],
    aim_at: Sequence[str],
) -> WorldTransform:
    """Aim ``controls[k]`` at joint ``aim_at[k]``, down the chain; return the last world frame.

    ``parent`` is the world transform the first control hangs from (read back
    from the rig), ``parent_name`` its name in the rest layout. Each control
    is placed by its rest offset (translation channels stay at rest).
    """
    if len(controls) != len(aim_at):
        raise ValueError(f"aim_chain: {len(controls)} controls but {len(aim_at)} aim targets")
    world, previous = parent, parent_name
    for control, child in zip(controls, aim_at, strict=True):
        pivot = world.apply(scene.rest_offset(control, previous))
        rest_direction = scene.rest_offset(child, control)
        wanted = rotate_back(world.R, scene.target(child) - pivot)
        angles = aim_angles(
            rest_direction, wanted, scene.used_axes(control), scene.rotation_order(control)
        )
        local = scene.set_euler(control, angles)
        world, previous = WorldTransform(world.R @ local, pivot), control
    return world


def match_fk_to_ik(
    scene: ScriptScene,
    parent: WorldTransform,
    fk_controls: Sequence[str],
    ik_frames: Sequence[WorldTransform],
) -> None:
    """IK→FK match: give each FK control the IK joint's orientation, relative to its parent.

    With ``ik_fk`` = 1 this changes no joint, but an animator who switches the
    limb to FK finds it where the IK put it.
    """
    previous = parent.R
    for control, frame in zip(fk_controls, ik_frames, strict=True):
        local = np.swapaxes(previous, -1, -2) @ frame.R
        scene.set_euler(control, matrix_to_euler(local, scene.rotation_order(control)))
        previous = frame.R
