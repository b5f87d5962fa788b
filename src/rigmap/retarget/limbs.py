"""IK limbs: the IK control on the end joint, the pole in the limb's plane, hock and toe.

What a TD's retarget script does for an IK limb: snap the IK control to the
wrist/ankle/paw target and orient it like the end joint (from the joints the
end carries), put the pole vector in the plane of the target limb on the side
the knee or elbow bends to, switch the limb to IK and leave the foot roll at
rest. A digitigrade leg's hock control turns the hock about the paw to the
target hock; a foot's toe tap turns the toe to the target toe. After the rig
has solved the IK, the FK controls are matched to it (see chains).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.retarget.chains import match_fk_to_ik
from rigmap.retarget.euler import matrix_to_euler
from rigmap.retarget.orient import (
    angle_about,
    frame_from_plane,
    rotate,
    rotate_back,
    rotation_between,
    unit,
)
from rigmap.retarget.scene import Readback, ScriptScene, WorldTransform


@dataclass(frozen=True)
class LimbLayout:
    """One limb of a rig, as its retarget script knows it (joint and control names).

    The end joint's orientation comes from ``carried`` (joints the end carries
    rigidly, e.g. finger bases) if given; else from end→``ball`` and
    ball→``toe`` (a foot: both lie in the foot's side plane); else from
    end→``toe`` and end→``hock`` (a digitigrade paw).
    """

    name: str
    upper: str
    mid: str
    end: str
    fk_parent: str
    hock: str | None = None
    ball: str | None = None
    toe: str | None = None
    carried: tuple[str, ...] = ()

    @classmethod
    def sided(cls, side: str, fk_parent: str, carried=(), **names: str) -> LimbLayout:
        """The layout of one side: ``_<side>`` appended to the limb's and every joint's name
        (``fk_parent`` and ``carried`` are taken as given)."""
        return cls(
            fk_parent=fk_parent,
            carried=tuple(carried),
            **{key: f"{value}_{side}" for key, value in names.items()},
        )

    @property
    def fk_joints(self) -> list[str]:
        joints = [self.upper, self.mid, self.hock, self.end, self.ball]
        return [j for j in joints if j is not None]

    def __post_init__(self) -> None:
        if not self.carried and self.toe is None:
            raise ValueError(f"limb {self.name!r}: needs carried joints or a toe to orient its end")
        if not self.carried and self.ball is None and self.hock is None:
            raise ValueError(
                f"limb {self.name!r}: a toe alone needs a ball or a hock for its plane"
            )


def end_orientation(scene: ScriptScene, limb: LimbLayout) -> np.ndarray:
    """World rotation of the limb's end joint implied by the joints beyond it."""
    if limb.carried:
        return scene.carried_orientation(limb.end, limb.carried)
    if limb.ball is not None:
        pairs = [(limb.ball, limb.end), (limb.toe, limb.ball)]
    else:
        pairs = [(limb.toe, limb.end), (limb.hock, limb.end)]

    def frame(vector) -> np.ndarray:
        return frame_from_plane(*(vector(child, base) for child, base in pairs))

    rest = frame(lambda child, base: scene.rest_offset(child, base))
    target = frame(lambda child, base: scene.target(child) - scene.target(base))
    return target @ np.swapaxes(rest, -1, -2)


def place_ik_limb(scene: ScriptScene, root: WorldTransform, limb: LimbLayout) -> None:
    """IK control, pole, hock and toe tap of ``limb`` from its target joints (root space)."""
    ik = f"{limb.name}_ik"
    end_R = end_orientation(scene, limb)
    scene.set_translation(
        ik, rotate_back(root.R, scene.target(limb.end) - root.t) - scene.rest_offset(ik, "root")
    )
    scene.set_euler(
        ik, matrix_to_euler(np.swapaxes(root.R, -1, -2) @ end_R, scene.rotation_order(ik))
    )
    pole = f"{limb.name}_pole"
    pole_world = _pole_position(scene, limb)
    scene.set_translation(
        pole, rotate_back(root.R, pole_world - root.t) - scene.rest_offset(pole, "root")
    )
    scene.set(f"{limb.name}.ik_fk", 1.0)
    if limb.hock is not None:
        # the hock control turns the hock offset about the paw's x axis
        wanted = rotate_back(end_R, scene.target(limb.hock) - scene.target(limb.end))
        angle = angle_about(scene.rest_offset(limb.hock, limb.end), wanted, "x")
        scene.set(f"{limb.name}_hock.rx", angle)
    tap = f"{limb.name}.toe_tap"
    if limb.ball is not None and limb.toe is not None and scene.is_used(tap):
        wanted = rotate_back(end_R, scene.target(limb.toe) - scene.target(limb.ball))
        # the reverse foot lifts the toes by −toe_tap about the foot's x axis
        scene.set(tap, -angle_about(scene.rest_offset(limb.toe, limb.ball), wanted, "x"))


def _pole_position(scene: ScriptScene, limb: LimbLayout) -> np.ndarray:
    """The pole at its rest distance from the mid joint, in the target limb's plane.

    A straight limb has no plane: the rest bend direction, turned with the limb, stands in.
    """
    chain_end = limb.hock or limb.end
    root, mid, end = (scene.target(j) for j in (limb.upper, limb.mid, chain_end))
    axis = unit(end - root)
    bend = (mid - root) - np.sum((mid - root) * axis, axis=-1, keepdims=True) * axis
    rest_axis = scene.rest_offset(chain_end, limb.upper)
    rest_bend = scene.rest_offset(limb.mid, limb.upper)
    rest_bend = rest_bend - (rest_bend @ rest_axis) / (rest_axis @ rest_axis) * rest_axis
    turned = rotate(rotation_between(rest_axis, axis), rest_bend)
    length = np.linalg.norm(rest_axis)
    straight = np.linalg.norm(bend, axis=-1, keepdims=True) < 1e-3 * length
    direction = unit(np.where(straight, turned, bend))
    distance = np.linalg.norm(scene.rest_offset(f"{limb.name}_pole", limb.mid))
    return mid + distance * direction


def match_limb_fk(scene: ScriptScene, readback: Readback, limb: LimbLayout) -> None:
    """Match the limb's FK controls to the IK pose in ``readback``."""
    match_fk_to_ik(
        scene,
        readback[limb.fk_parent],
        [f"{j}_fk" for j in limb.fk_joints],
        [readback[j] for j in limb.fk_joints],
    )
