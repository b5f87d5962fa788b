"""Head and eyes: the head control from the joints the head carries, eye_aim from the gaze.

The head is an orient constraint to its rigidly carried joints (snout/top,
jaw pivot, eyes, ear bases), expressed in the neck's frame with ``follow`` = 1.
The eye aim control goes where both eyes look: each eye's look direction is
its eye→pupil line; the aim point is the least-squares meeting point of the
two lines (with the per-eye offsets of the aim rig), held at its rest
distance when the lines are near parallel and the depth cannot be seen, or
when they meet behind (or right in front of) the eyes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rigmap.retarget.euler import matrix_to_euler
from rigmap.retarget.orient import orthonormalize, rotate, rotate_back, unit
from rigmap.retarget.scene import Readback, ScriptScene, WorldTransform

# weight of the rest-distance prior against the eyes' lines (per unit of squared angle)
DEPTH_PRIOR_WEIGHT = 1e-3
# a meeting point nearer than this fraction of the rest distance (or behind) is not trusted
NEAREST_DEPTH_FRACTION = 0.25


def place_head(
    scene: ScriptScene, readback: Readback, neck_end: str, carried: Sequence[str]
) -> None:
    """Head control rotation from the carried joints, in the space of the neck's last joint."""
    world = scene.carried_orientation("head", tuple(carried))
    host = orthonormalize(readback[neck_end].R)
    scene.set("head.follow", 1.0)
    local = np.swapaxes(host, -1, -2) @ world
    scene.set_euler("head", matrix_to_euler(local, scene.rotation_order("head")))


def place_eye_aim(
    scene: ScriptScene, root: WorldTransform, eyes: Sequence[tuple[str, str, str]]
) -> None:
    """``eye_aim`` (in root space) from ``(eye, pupil, per-eye aim control)`` triples."""
    system = np.zeros((scene.n, 3, 3))
    rhs = np.zeros((scene.n, 3))
    prior = np.zeros((scene.n, 3))
    eye = np.eye(3)
    lines = []
    for eye_joint, pupil, aim in eyes:
        centre = scene.target(eye_joint)
        look = unit(scene.target(pupil) - centre)
        side = rotate(root.R, scene.rest_offset(aim, "eye_aim"))
        depth = np.linalg.norm(scene.rest_offset(aim, eye_joint))
        lines.append((centre, look, side, depth))
        # distance of (P + side) from the look line, squared: |(I − l lᵀ)(P + side − centre)|²
        across = eye - look[:, :, None] * look[:, None, :]
        system += across
        rhs += np.einsum("nij,nj->ni", across, centre - side)
        prior += centre + depth * look - side
    prior /= len(eyes)
    system += DEPTH_PRIOR_WEIGHT * eye
    rhs += DEPTH_PRIOR_WEIGHT * prior
    point = np.linalg.solve(system, rhs[..., None])[..., 0]
    in_front = np.ones(scene.n, dtype=bool)
    for centre, look, side, depth in lines:
        ahead = np.sum((point + side - centre) * look, axis=-1)
        in_front &= ahead >= NEAREST_DEPTH_FRACTION * depth
    point = np.where(in_front[:, None], point, prior)
    local = rotate_back(root.R, point - root.t) - scene.rest_offset("eye_aim", "root")
    scene.set_translation("eye_aim", local)
