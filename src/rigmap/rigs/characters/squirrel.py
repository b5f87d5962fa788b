"""The built-in squirrel: a squashy cartoon mesh rig like the paper's (§6.3, Fig. 9, Table 3).

Centimetres, Y up, the squirrel sits on the ground facing +Z, +X is its left.
A closed mesh of 1 125 vertices in watertight parts (body with neck, head with
snout, nose, eyes, ears, two incisors, arms, feet, a bushy tail). Its "joints"
are all 1 125 vertices (3 375 numbers), relative to the centre of gravity.

Deformer stack, in evaluation order (like a Maya deformer stack):

1. a Bernstein lattice (3 x 6 x 3 control points) around the whole squirrel,
   its control points moved by whole-body squash-stretch, twist, side bend and
   forward bend;
2. a skeleton riding on that lattice (each bone's rest frame is carried by the
   lattice at its pivot) whose FK controls drive linear blend skinning of the
   neck (two segments plus a chain ``neck.bend``), head (with squash), ears,
   arms and a five-segment tail (plus ``tail.curl``);
3. blendshapes carried by the posed bones: cheek puff and tail fluff (sliders
   hard-clamped to [0, 1]);
4. the collision corrective: when the neck bends forward the neck and chest
   sink under the teeth so the teeth never enter the body (the paper's
   "the neck part sinks when the neck bends forward");
5. the placement (root translate and heading), applied rigidly.

The centre of gravity is the rest body centre (0, 13, 0) cm carried by the
lattice and the placement; its rotation is the placement's heading times the
lattice's local rotation there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from rigmap.rigs.base import Control
from rigmap.rigs.characters.palettes import palette
from rigmap.rigs.engine.transforms import Transform, axis_rotation, euler_matrix, orthonormalize
from rigmap.rigs.mesh.blendshapes import Blendshapes, ShapeSpec
from rigmap.rigs.mesh.collision import CollisionSink
from rigmap.rigs.mesh.geometry import (
    MeshAssembly,
    TriangleMesh,
    ellipsoid_point,
    polyline_resample,
    superellipsoid_point,
    surface_of_revolution,
    swept_tube,
    vertex_normals,
)
from rigmap.rigs.mesh.lattice import BernsteinLattice, blend_rows, deform
from rigmap.rigs.mesh.lattice_deformers import bend, squash_stretch, twist
from rigmap.rigs.mesh.rig import DeformedMesh, MeshRig
from rigmap.rigs.mesh.shaping import ramps_to_weights, smoothstep
from rigmap.rigs.mesh.skinning import (
    Bone,
    LinearBlendSkin,
    Skeleton,
    apply_blended,
    skinning_transforms,
)

BODY_CENTER = (0.0, 13.0, 0.0)
NECK_BEND_SHARES = {"neck_1": 0.25, "neck_2": 0.25, "head": 0.50}  # of neck.bend (radians)
TAIL_SEGMENTS = 5

# an expressive pose for pictures: head curled down onto the chest (which sinks),
# body squashed and leaning, tail curled and fluffed, cheeks full
SHOWCASE_POSE = {
    "neck.bend": 1.5,
    "head.rz": 0.15,
    "tail.curl": 0.9,
    "tail_3.ry": 0.3,
    "body.bend_side": 0.25,
    "body.twist": 0.3,
    "body.squash": -0.2,
    "cheeks.puff": 1.0,
    "tail.fluff": 1.0,
    "ear_l.rx": 0.6,
    "arm_l.rx": -0.9,
    "arm_r.rx": 0.4,
}

#: the named colours of the renders (``palettes.yaml``)
COLOURS = palette("squirrel")


# whole-body lattice deformers: base height and length of the bent column (cm)
# the snout in front of this depth (cm ahead of the head centre) also pushes the chest in
SNOUT_COLLIDER_FROM = 3.0
BEND_BASE, BEND_LENGTH = 3.0, 30.0
TWIST_BASE, TWIST_LENGTH = 2.0, 30.0


@dataclass
class SquirrelModel:
    """Everything built once: mesh, skeleton, weights, lattice, shapes, corrective."""

    mesh: TriangleMesh
    skeleton: Skeleton
    skin: LinearBlendSkin
    lattice: BernsteinLattice
    shapes: Blendshapes
    collision: CollisionSink


def build_squirrel(*, neck_collision: bool = True, chunk: int = 1024) -> SquirrelRig:
    """The squirrel rig; ``neck_collision=False`` switches the corrective off (for comparison)."""
    return SquirrelRig(build_squirrel_model(), neck_collision=neck_collision, chunk=chunk)


class SquirrelRig(MeshRig):
    """Lattice + skinning + shapes + collision corrective, 36 controls -> 1 125 vertices."""

    def __init__(self, model: SquirrelModel, *, neck_collision: bool = True, chunk: int = 1024):
        mesh = model.mesh
        super().__init__(
            name="squirrel",
            controls=squirrel_controls(),
            rest_vertices=mesh.vertices,
            faces=mesh.faces,
            joint_vertices=np.arange(mesh.n_vertices),
            joint_names=[f"v{i:04d}" for i in range(mesh.n_vertices)],
            description=(
                "Cartoon squirrel mesh rig: lattice bend/twist/squash, skinned neck/head/tail, "
                "cheek and tail shapes, neck-sink collision corrective (cm, radians)"
            ),
            face_colors=mesh.face_colors,
            chunk=chunk,
        )
        self.model = model
        self.neck_collision = bool(neck_collision)
        self.part_vertices = mesh.part_vertices
        self.teeth_vertices = mesh.vertices_of("tooth_l", "tooth_r")
        self.body_vertices = mesh.part_vertices["body"]
        self.body_faces = mesh.faces[mesh.part_faces["body"]]
        lattice = model.lattice
        pivots = model.skeleton.pivots
        self._lattice_weights = lattice.weights(mesh.vertices)
        self._pivot_weights = lattice.weights(pivots)
        self._pivot_jacobian = lattice.jacobian_weights(pivots)
        self._cog_weights = lattice.weights(np.array([BODY_CENTER]))
        self._cog_jacobian = lattice.jacobian_weights(np.array([BODY_CENTER]))
        self._shape_support = np.flatnonzero(np.abs(model.shapes.deltas).sum(axis=(0, 2)) > 0)
        # d(lattice image)/dz at each sinking vertex: its forward axis carried by the lattice
        region = model.collision.region
        self._region_depth_slope = lattice.jacobian_weights(mesh.vertices[region])[:, 2]

    # --- evaluation ------------------------------------------------------------
    def _deform(self, Y: torch.Tensor, vertex_index) -> DeformedMesh:
        model, dtype, n = self.model, Y.dtype, Y.shape[0]
        const = self.constant

        control_points = self._lattice_control_points(Y)
        vertices = deform(const("lattice.weights", self._lattice_weights, dtype), control_points)

        # bones ride on the lattice: pivot carried, frame = lattice's local rotation there
        pivots = deform(const("lattice.pivots", self._pivot_weights, dtype), control_points)
        rest_frames = _lattice_frames(
            const("lattice.pivot_jacobian", self._pivot_jacobian, dtype), control_points, pivots
        )
        posed = model.skeleton.forward_kinematics(rest_frames, self._local_matrices(Y))
        skins = skinning_transforms(rest_frames, posed)
        weights = const("skin.weights", model.skin.weights, dtype)
        vertices = model.skin.apply(vertices, skins, weights)

        # shapes are sculpted in rest space; the posed bones carry them (only where they act)
        support = self._shape_support
        shape_weights = model.shapes.clamp(self._shape_values(Y))
        deltas = const("shapes.deltas", model.shapes.deltas[:, support], dtype)
        offsets = model.shapes.offsets(shape_weights, deltas)
        carry = torch.stack([frame.R for frame in posed], dim=1).reshape(n, len(posed), 9)
        carry = blend_rows(const("shapes.skin", model.skin.weights[support], dtype), carry)
        vertices = vertices.index_add(1, torch.as_tensor(support), apply_blended(carry, offsets))

        if self.neck_collision:
            # sink along the body's backward axis as the lattice carries it at each vertex
            backward = -deform(
                const("collision.depth_slope", self._region_depth_slope, dtype), control_points
            )
            sink_direction = backward / torch.linalg.vector_norm(backward, dim=-1, keepdim=True)
            region_weight = const("collision.weight", model.collision.region_weight, dtype)
            push = model.collision.push(vertices, sink_direction, region_weight)
            vertices = vertices.index_add(1, torch.as_tensor(model.collision.region), push)

        heading = axis_rotation(self.column(Y, "root.ry"), "y")
        translate = torch.stack([self.column(Y, f"root.{c}") for c in ("tx", "ty", "tz")], dim=1)
        vertices = vertices @ heading.transpose(1, 2) + translate[:, None, :]
        cog_local = deform(const("lattice.cog", self._cog_weights, dtype), control_points)
        cog_frame = _lattice_frames(
            const("lattice.cog_jacobian", self._cog_jacobian, dtype), control_points, cog_local
        )[0]
        cog = (heading @ cog_local[:, 0, :, None])[..., 0] + translate
        if vertex_index is not None:
            vertices = vertices[:, torch.as_tensor(vertex_index)]
        return DeformedMesh(vertices, cog, heading @ cog_frame.R)

    def _lattice_control_points(self, Y: torch.Tensor) -> torch.Tensor:
        rest = self.constant("lattice.rest", self.model.lattice.rest_control_points, Y.dtype)
        points = rest.expand(Y.shape[0], -1, -1)
        points = squash_stretch(points, self.column(Y, "body.squash"), base=0.0, center_xz=(0, 0))
        points = twist(
            points,
            self.column(Y, "body.twist"),
            base=TWIST_BASE,
            length=TWIST_LENGTH,
            center_xz=(0.0, 0.0),
        )
        for control, axis in (("body.bend_side", "x"), ("body.bend_forward", "z")):
            amount = self.column(Y, control)
            points = bend(points, amount, base=BEND_BASE, length=BEND_LENGTH, axis=axis, center=0.0)
        return points

    def _local_matrices(self, Y: torch.Tensor) -> dict[str, torch.Tensor]:
        def rotation(prefix: str, extra_rx=None) -> torch.Tensor:
            angles = torch.stack([self.column(Y, f"{prefix}.r{a}") for a in "xyz"], dim=1)
            if extra_rx is not None:
                angles = angles + torch.stack(
                    [extra_rx, torch.zeros_like(extra_rx), torch.zeros_like(extra_rx)], dim=1
                )
            return euler_matrix(angles, "xyz")

        bend_amount = self.column(Y, "neck.bend")
        squash = self.column(Y, "head.squash")
        stretch = torch.stack(
            [torch.exp(-0.5 * squash), torch.exp(squash), torch.exp(-0.5 * squash)], dim=1
        )
        local = {
            "neck_1": rotation("neck_1", NECK_BEND_SHARES["neck_1"] * bend_amount),
            "neck_2": rotation("neck_2", NECK_BEND_SHARES["neck_2"] * bend_amount),
            "head": rotation("head", NECK_BEND_SHARES["head"] * bend_amount) * stretch[:, None, :],
        }
        for side in ("l", "r"):
            local[f"ear_{side}"] = axis_rotation(self.column(Y, f"ear_{side}.rx"), "x")
            local[f"arm_{side}"] = axis_rotation(self.column(Y, f"arm_{side}.rx"), "x")
        curl = self.column(Y, "tail.curl") / TAIL_SEGMENTS
        for k in range(1, TAIL_SEGMENTS + 1):
            rx = self.column(Y, f"tail_{k}.rx") + curl
            ry = self.column(Y, f"tail_{k}.ry")
            local[f"tail_{k}"] = euler_matrix(torch.stack([rx, ry, torch.zeros_like(rx)], 1), "xyz")
        return local

    def _shape_values(self, Y: torch.Tensor) -> torch.Tensor:
        return torch.stack([self.column(Y, name) for name in self.model.shapes.names], dim=1)


def _lattice_frames(jacobian_weights, control_points, origins) -> list[Transform]:
    """Rigid frames carried by the lattice: its local rotation at each point, at ``origins``."""
    # J[n, b, a, c] = d(deformed c) / d(rest a): rows are the images of the rest axes
    J = torch.einsum("bak,nkc->nbac", jacobian_weights, control_points)
    R = orthonormalize(J.transpose(-1, -2))  # columns = images of the rest axes
    return [Transform(R[:, b], origins[:, b]) for b in range(origins.shape[1])]


# --- controls -----------------------------------------------------------------
def squirrel_controls() -> list[Control]:
    """36 controls, all keyed by the animators (cm, radians, slider factors)."""

    def c(name, kind, lower, upper, group, default=0.0):
        return Control(name, kind, default, lower, upper, True, group)

    controls = [
        c("root.tx", "translate", -30.0, 30.0, "root"),
        c("root.ty", "translate", -10.0, 30.0, "root"),
        c("root.tz", "translate", -30.0, 30.0, "root"),
        c("root.ry", "rotate", -np.pi, np.pi, "root"),
        c("body.bend_forward", "rotate", -0.6, 0.9, "body"),
        c("body.bend_side", "rotate", -0.6, 0.6, "body"),
        c("body.twist", "rotate", -0.7, 0.7, "body"),
        c("body.squash", "scalar", -0.4, 0.4, "body"),
        c("neck.bend", "rotate", -0.6, 1.8, "neck"),
    ]
    for segment in ("neck_1", "neck_2"):
        controls += [
            c(f"{segment}.rx", "rotate", -0.6, 0.8, "neck"),
            c(f"{segment}.ry", "rotate", -0.7, 0.7, "neck"),
            c(f"{segment}.rz", "rotate", -0.4, 0.4, "neck"),
        ]
    controls += [
        c("head.rx", "rotate", -0.7, 0.9, "head"),
        c("head.ry", "rotate", -0.9, 0.9, "head"),
        c("head.rz", "rotate", -0.5, 0.5, "head"),
        c("head.squash", "scalar", -0.35, 0.35, "head"),
        c("cheeks.puff", "scalar", 0.0, 1.0, "head"),
        c("ear_l.rx", "rotate", -0.5, 0.9, "head"),
        c("ear_r.rx", "rotate", -0.5, 0.9, "head"),
        c("arm_l.rx", "rotate", -1.2, 0.8, "arms"),
        c("arm_r.rx", "rotate", -1.2, 0.8, "arms"),
        c("tail.curl", "rotate", -0.6, 1.0, "tail"),
        c("tail.fluff", "scalar", 0.0, 1.0, "tail"),
    ]
    for k in range(1, TAIL_SEGMENTS + 1):
        controls += [
            c(f"tail_{k}.rx", "rotate", -0.7, 0.7, "tail"),
            c(f"tail_{k}.ry", "rotate", -0.7, 0.7, "tail"),
        ]
    return controls


# --- the model ------------------------------------------------------------------
SPINE = np.array(
    [
        (0.0, 1.6, -1.4),
        (0.0, 6.0, -1.2),
        (0.0, 11.0, -0.2),
        (0.0, 16.0, 0.9),
        (0.0, 20.0, 2.0),
        (0.0, 23.4, 3.2),
        (0.0, 26.0, 4.2),
    ]
)
# (arc-length fraction, depth radius, width radius) in cm along the spine
BODY_PROFILE = np.array(
    [
        (0.00, 3.0, 3.2),
        (0.07, 5.6, 6.0),
        (0.20, 7.0, 7.4),
        (0.34, 6.8, 7.0),
        (0.50, 5.9, 5.9),
        (0.63, 5.0, 5.2),
        (0.74, 3.6, 3.7),
        (0.86, 3.0, 3.1),
        (1.00, 2.6, 2.7),
    ]
)
HEAD_CENTER = np.array([0.0, 28.0, 5.4])
HEAD_RADII = np.array([4.3, 4.1, 4.5])  # width, height, depth (cm)
HEAD_COLUMNS = 16
BODY_RINGS, BODY_COLUMNS = 20, 16
TAIL_CURVE = np.array(
    [
        (0.0, 4.0, -4.5),
        (0.0, 5.0, -10.5),
        (0.0, 10.0, -15.5),
        (0.0, 18.5, -17.5),
        (0.0, 27.0, -15.5),
        (0.0, 32.5, -10.5),
        (0.0, 32.5, -5.0),
    ]
)
TAIL_PROFILE = np.array([(0.0, 2.4), (0.12, 3.6), (0.35, 5.0), (0.6, 5.2), (0.85, 4.2), (1.0, 2.2)])


def build_squirrel_model() -> SquirrelModel:
    assembly = MeshAssembly()
    body, spine_u = _body()
    # a light belly: whole grid quads facing forward, from the haunches to the throat
    ring, column = np.divmod(np.arange(len(body.vertices)) - 1, BODY_COLUMNS)
    facing = np.minimum(column, BODY_COLUMNS - column) <= 3
    belly = (ring >= 1) & (ring <= 14) & facing
    belly[[0, -1]] = False  # the poles
    colors = np.where(belly[body.faces].all(axis=1)[:, None], COLOURS["belly"], COLOURS["fur"])
    assembly.add("body", body, colors)
    head = _head()
    assembly.add("head", head, COLOURS["fur"])
    nose_tip = _snout_point(1.0, 0.0, 0.0)
    assembly.add(
        "nose",
        surface_of_revolution(
            ellipsoid_point(nose_tip + np.array([0, 0.05, -0.25]), (0.75, 0.55, 0.6)),
            np.linspace(0.4, np.pi - 0.4, 3),
            7,
        ),
        COLOURS["nose"],
    )
    for side, sign in (("l", 1.0), ("r", -1.0)):
        eye_center = _on_head((sign * 0.62, 0.30, 0.64), inset=0.45)
        assembly.add(
            f"eye_{side}",
            surface_of_revolution(
                ellipsoid_point(eye_center, (0.95, 1.05, 0.95)), np.linspace(0.5, np.pi - 0.5, 4), 9
            ),
            COLOURS["dark"],
        )
    for side, sign in (("l", 1.0), ("r", -1.0)):
        assembly.add(f"ear_{side}", _ear(sign), COLOURS["ear_inner"])
    for side, sign in (("l", 1.0), ("r", -1.0)):
        tooth = _tooth(sign)
        assembly.add(f"tooth_{side}", tooth, COLOURS["teeth"])
    for side, sign in (("l", 1.0), ("r", -1.0)):
        arm, _ = _arm(sign)
        assembly.add(f"arm_{side}", arm, COLOURS["fur"])
    for side, sign in (("l", 1.0), ("r", -1.0)):
        assembly.add(
            f"foot_{side}",
            surface_of_revolution(
                ellipsoid_point(
                    (sign * 4.4, 1.1, 4.2), (1.7, 1.15, 3.4), rotation=_yaw(sign * 0.25)
                ),
                np.linspace(0.45, np.pi - 0.45, 3),
                8,
            ),
            COLOURS["fur"],
        )
    tail, tail_u = _tail()
    assembly.add("tail", tail, COLOURS["tail_fur"])
    mesh = assembly.build()

    skeleton = _skeleton()
    weights = _skin_weights(mesh, skeleton, spine_u, tail_u)
    skin = LinearBlendSkin(weights, skeleton.names)
    lattice = BernsteinLattice((-13.0, -1.0, -23.0), (13.0, 40.0, 17.0), degrees=(2, 5, 2))
    shapes = _shapes(mesh, tail_u)
    collision = _neck_sink(mesh)
    return SquirrelModel(mesh, skeleton, skin, lattice, shapes, collision)


def _body() -> tuple[TriangleMesh, np.ndarray]:
    rows, cols = BODY_RINGS, BODY_COLUMNS
    curve = polyline_resample(SPINE, rows)
    u = np.linspace(0, 1, rows)
    radii = np.stack(
        [
            np.interp(u, BODY_PROFILE[:, 0], BODY_PROFILE[:, 1]),
            np.interp(u, BODY_PROFILE[:, 0], BODY_PROFILE[:, 2]),
        ],
        axis=1,
    )
    body = swept_tube(curve, radii, cols, up=(0.0, 0.0, 1.0), cap_extension=0.55)
    # arc-length fraction per vertex: poles then rings
    spine_u = np.concatenate([[0.0], np.repeat(u, cols), [1.0]])
    return body, spine_u


def _snout_point(f: float, x_unit: float, y_unit: float) -> np.ndarray:
    """Head surface point: ``f`` = cos(angle from the snout axis); unit cross-section offsets."""
    forward = max(f, 0.0)
    z = HEAD_RADII[2] * f * (1 + 0.55 * forward**2)
    x = HEAD_RADII[0] * x_unit * (1 - 0.40 * forward**2)
    y = HEAD_RADII[1] * y_unit * (1 - 0.36 * forward**2) - 0.9 * forward**2
    return HEAD_CENTER + np.array([x, y, z])


def _head() -> TriangleMesh:
    def point(theta, phi):
        theta, phi = np.broadcast_arrays(theta, phi)
        f = np.cos(theta)
        forward = np.clip(f, 0.0, None)
        s = np.sin(theta)
        x = HEAD_RADII[0] * s * np.sin(phi) * (1 - 0.40 * forward**2)
        y = HEAD_RADII[1] * s * np.cos(phi) * (1 - 0.36 * forward**2) - 0.9 * forward**2
        z = HEAD_RADII[2] * f * (1 + 0.55 * forward**2)
        # the back of the skull a little flatter, the crown a little higher
        z = np.where(f < 0, z * 0.92, z)
        return np.stack([x, y, z], axis=-1) + HEAD_CENTER

    # polar axis along +z: theta = 0 is the snout tip; rings denser near the snout
    t = np.linspace(0, 1, 16)[1:-1]
    thetas = np.pi * (0.15 * t + 0.85 * t**1.4)
    return surface_of_revolution(point, thetas, HEAD_COLUMNS)


def _on_head(direction, inset: float) -> np.ndarray:
    """The head surface point in ``direction`` (unit-radius space), pulled in by ``inset`` cm."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    p = _snout_point(d[2], d[0], d[1])
    return p - (p - HEAD_CENTER) / np.linalg.norm(p - HEAD_CENTER) * inset


def _ear(sign: float) -> TriangleMesh:
    base = HEAD_CENTER + np.array([sign * 2.5, 3.2, -1.4])
    tilt = _roll(-sign * 0.35)

    def point(theta, phi):
        theta, phi = np.broadcast_arrays(theta, phi)
        y = 1.9 * (1 - np.cos(theta))  # 0 at the base pole, 3.8 at the tip
        taper = np.sin(theta) * (1 - 0.55 * (y / 3.8) ** 1.5)
        local = np.stack([1.2 * taper * np.sin(phi), y, 0.45 * taper * np.cos(phi)], axis=-1)
        return local @ tilt.T + base

    return surface_of_revolution(point, np.linspace(0.5, np.pi - 0.35, 4), 8)


def _tooth(sign: float) -> TriangleMesh:
    """One incisor below the snout tip, sticking out of the upper jaw."""
    under_snout = _snout_point(0.93, 0.0, -0.37)
    center = under_snout + np.array([sign * 0.34, -0.55, -0.05])
    return surface_of_revolution(
        superellipsoid_point(center, (0.30, 0.75, 0.24), 0.4), np.linspace(0.35, np.pi - 0.35, 3), 8
    )


def _arm(sign: float) -> tuple[TriangleMesh, np.ndarray]:
    curve = polyline_resample(
        np.array([(sign * 3.0, 19.0, 2.2), (sign * 4.6, 15.5, 4.6), (sign * 3.0, 12.6, 7.2)]), 6
    )
    radii = np.array([1.5, 1.3, 1.1, 1.0, 1.05, 1.2])
    arm = swept_tube(curve, radii, 8, up=(0.0, 0.0, 1.0), cap_extension=0.7)
    u = np.concatenate([[0.0], np.repeat(np.linspace(0, 1, 6), 8), [1.0]])
    return arm, u


def _tail() -> tuple[TriangleMesh, np.ndarray]:
    rows, cols = 17, 12
    curve = polyline_resample(TAIL_CURVE, rows)
    u = np.linspace(0, 1, rows)
    radius = np.interp(u, TAIL_PROFILE[:, 0], TAIL_PROFILE[:, 1])
    tail = swept_tube(
        curve, np.stack([radius, radius * 0.85], 1), cols, up=(1.0, 0.0, 0.0), cap_extension=0.6
    )
    return tail, np.concatenate([[0.0], np.repeat(u, cols), [1.0]])


def _tail_pivots() -> np.ndarray:
    curve = polyline_resample(TAIL_CURVE, 101)
    return curve[np.round(100 * _tail_pivot_fractions()).astype(int)]


def _tail_pivot_fractions() -> np.ndarray:
    return np.linspace(0.10, 0.78, TAIL_SEGMENTS)


def _skeleton() -> Skeleton:
    bones = [
        Bone("body", None, BODY_CENTER),
        Bone("neck_1", "body", (0.0, 19.6, 1.9)),
        Bone("neck_2", "neck_1", (0.0, 22.6, 2.9)),
        Bone("head", "neck_2", (0.0, 25.4, 3.9)),
        Bone("ear_l", "head", tuple(HEAD_CENTER + np.array([2.5, 3.2, -1.4]))),
        Bone("ear_r", "head", tuple(HEAD_CENTER + np.array([-2.5, 3.2, -1.4]))),
        Bone("arm_l", "body", (3.0, 19.0, 2.2)),
        Bone("arm_r", "body", (-3.0, 19.0, 2.2)),
    ]
    parent = "body"
    for k, pivot in enumerate(_tail_pivots(), start=1):
        bones.append(Bone(f"tail_{k}", parent, tuple(pivot)))
        parent = f"tail_{k}"
    return Skeleton(bones)


def _skin_weights(mesh: TriangleMesh, skeleton: Skeleton, spine_u, tail_u) -> np.ndarray:
    W = np.zeros((mesh.n_vertices, len(skeleton)))
    col = skeleton.index

    def assign(part: str, bone: str) -> None:
        W[mesh.part_vertices[part], col[bone]] = 1.0

    body = mesh.part_vertices["body"]
    chain = ramps_to_weights(
        [
            smoothstep(0.62, 0.80, spine_u),
            smoothstep(0.76, 0.92, spine_u),
            smoothstep(0.92, 1.0, spine_u),
        ]
    )
    for k, bone in enumerate(("body", "neck_1", "neck_2", "head")):
        W[body, col[bone]] = chain[:, k]
    for part in ("head", "nose", "eye_l", "eye_r", "tooth_l", "tooth_r"):
        assign(part, "head")
    for side in ("l", "r"):
        assign(f"ear_{side}", f"ear_{side}")
        assign(f"foot_{side}", "body")
        arm = mesh.part_vertices[f"arm_{side}"]
        arm_u = np.concatenate([[0.0], np.repeat(np.linspace(0, 1, 6), 8), [1.0]])
        share = smoothstep(0.0, 0.35, arm_u)
        W[arm, col["body"]] = 1 - share
        W[arm, col[f"arm_{side}"]] = share
    tail = mesh.part_vertices["tail"]
    fractions = _tail_pivot_fractions()
    ramps = [smoothstep(t - 0.07, t + 0.07, tail_u) for t in fractions]
    tail_weights = ramps_to_weights(ramps)
    W[tail, col["body"]] = tail_weights[:, 0]
    for k in range(1, TAIL_SEGMENTS + 1):
        W[tail, col[f"tail_{k}"]] = tail_weights[:, k]
    return W


def _shapes(mesh: TriangleMesh, tail_u) -> Blendshapes:
    V = mesh.n_vertices
    normals = vertex_normals(mesh.vertices, mesh.faces)
    # cheek puff: the sides of the snout swell (a squirrel with its cheeks full of nuts)
    puff = np.zeros((V, 3))
    head = mesh.part_vertices["head"]
    local = mesh.vertices[head] - HEAD_CENTER
    for sign in (1.0, -1.0):
        center = np.array([sign * 2.6, -1.6, 2.6])
        d = np.linalg.norm((local - center) / (1.9, 1.6, 2.0), axis=1)
        puff[head] += (1.6 * smoothstep(1.0, 0.0, d))[:, None] * normals[head]
    # tail fluff: the tail swells radially, most in the middle
    fluff = np.zeros((V, 3))
    tail = mesh.part_vertices["tail"]
    amount = 1.8 * np.sin(np.pi * np.clip(tail_u, 0, 1)) ** 0.7
    fluff[tail] = amount[:, None] * normals[tail]
    return Blendshapes([ShapeSpec("cheeks.puff", puff), ShapeSpec("tail.fluff", fluff)], V)


def _neck_sink(mesh: TriangleMesh) -> CollisionSink:
    """The front of the neck and chest gives way to the incisors."""
    body = mesh.part_vertices["body"]
    normals = vertex_normals(mesh.vertices, mesh.faces)[body]
    height = mesh.vertices[body, 1]
    # the front of the body from the haunches up; the neck's top, hidden in the head, stays
    front = smoothstep(-0.1, 0.3, normals[:, 2]) * smoothstep(2.0, 4.0, height)
    keep = (front > 1e-3) & (height < 24.5)
    # the snout, every other ring and column of the head grid (the margin covers the gaps)
    head = mesh.part_vertices["head"]
    ring, column = np.divmod(np.arange(len(head)) - 1, HEAD_COLUMNS)
    sparse = (ring % 2 == 0) & (column % 2 == 0)
    snout = head[sparse & (mesh.vertices[head, 2] > HEAD_CENTER[2] + SNOUT_COLLIDER_FROM)]
    # the incisors below where they leave the snout (their roots are inside it)
    teeth = mesh.vertices_of("tooth_l", "tooth_r")
    teeth = teeth[mesh.vertices[teeth, 1] < mesh.vertices[teeth, 1].max() - 0.1]
    return CollisionSink(mesh.vertices, body[keep], front[keep], np.concatenate([teeth, snout]))


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _roll(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


__all__ = ["SquirrelModel", "SquirrelRig", "build_squirrel", "build_squirrel_model"]
