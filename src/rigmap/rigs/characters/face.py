"""The built-in face: a landmark face rig like the paper's FaceIK example (§6.3, Fig. 10, Table 3).

Centimetres, Y up, the face looks along +Z, +X is the character's left. A
procedural head (ellipsoid with brow ridge, eye sockets and eyes, nose with
nostrils, cheeks, lips with a mouth slit, chin, ears) of 3 362 vertices,
deformed like a production face rig, in this order:

1. 46 blendshape sliders (brows, lids, cheeks, nose, mouth), each
   hard-clamped to its range ([0, 1], ``mouth_shift`` [-1, 1]);
2. 6 corrective combination shapes whose weights are products of their
   drivers' weights (jaw-open x smile L/R, both inner brows up, smile x cheek
   raise L/R, jaw-open x pucker) — the map is nonlinear in the controls;
3. a jaw bone (open ``jaw.rx`` and side ``jaw.ry`` in radians, forward
   ``jaw.tz`` in cm) about a hinge in front of the ears, skinning the lower
   face with smooth weights (the lower lip fully, the mouth corners half).

Its "joints" are six landmark vertices — brows, mouth corners, upper lip,
chin — 18 numbers for 49 controls: the most ambiguous rig of Table 3. The
centre of gravity is a fixed pivot at the top of the neck, (0, -8, -1.5) cm,
with identity rotation (the face rig has no head placement controls).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from rigmap.rigs.base import Control
from rigmap.rigs.characters.palettes import palette
from rigmap.rigs.engine.transforms import axis_rotation
from rigmap.rigs.mesh.blendshapes import (
    Blendshapes,
    CombinationShapes,
    CombinationSpec,
    ShapeSpec,
    clamp_between,
)
from rigmap.rigs.mesh.geometry import TriangleMesh, closed_grid, vertex_normals
from rigmap.rigs.mesh.rig import DeformedMesh, MeshRig
from rigmap.rigs.mesh.shaping import gaussian_bump, smoothstep

HEAD_RADII = (7.6, 11.0, 9.6)  # half width, half height, half depth (cm)
COG = (0.0, -8.0, -1.5)
JAW_PIVOT = (0.0, -1.2, -1.8)
JAW_OPEN_FULL = 0.35  # radians of jaw.rx at which jaw-driven correctives are fully on
MOUTH_Y = -4.2  # the mouth slit (cm)
MOUTH_HALF_WIDTH = 2.45
EYE = (3.1, 1.15)  # left eye centre (x, y)
EYE_HALF_WIDTH, EYE_UPPER, EYE_LOWER = 1.45, 0.62, 0.42
LANDMARKS = {
    "brow_l": (2.9, 2.95),
    "brow_r": (-2.9, 2.95),
    "mouth_corner_l": (MOUTH_HALF_WIDTH, MOUTH_Y),
    "mouth_corner_r": (-MOUTH_HALF_WIDTH, MOUTH_Y),
    "upper_lip": (0.0, -3.75),
    "chin": (0.0, -7.2),
}

# an expressive pose for pictures (laughing: smile, cheeks, open jaw; correctives active)
SHOWCASE_POSE = {
    "mouth_smile_l": 1.0,
    "mouth_smile_r": 0.9,
    "cheek_raise_l": 0.8,
    "cheek_raise_r": 0.8,
    "eye_squint_l": 0.5,
    "eye_squint_r": 0.5,
    "brow_inner_up_l": 0.6,
    "brow_inner_up_r": 0.6,
    "brow_outer_up_l": 0.3,
    "jaw.rx": 0.26,
    "jaw.ry": 0.04,
    "nostril_flare_l": 0.5,
    "nostril_flare_r": 0.5,
}

#: the named colours of the renders (``palettes.yaml``)
COLOURS = palette("face")


def build_face(*, chunk: int = 4096) -> FaceRig:
    """The face rig (49 controls -> 6 landmarks)."""
    return FaceRig(build_face_model(), chunk=chunk)


@dataclass
class FaceModel:
    mesh: TriangleMesh
    shapes: Blendshapes
    correctives: CombinationShapes
    jaw_weights: np.ndarray  # (V,)
    landmarks: np.ndarray  # (6,) vertex indices


class FaceRig(MeshRig):
    """Blendshapes + correctives + jaw skinning; landmarks as joints."""

    def __init__(
        self,
        model: FaceModel,
        *,
        chunk: int = 4096,
        name: str = "face",
        controls: list[Control] | None = None,
        description: str = (
            "Procedural face: 46 clamped blendshape sliders, 6 combination correctives, "
            "skinned jaw; 6 landmarks (cm, radians)"
        ),
    ):
        """``controls`` default to :func:`face_controls`; a face driven by other controls
        (:mod:`rigmap.rigs.characters.arkit_face`) names its own and maps them in ``_deform``."""
        sliders = face_controls(model.shapes)
        super().__init__(
            name=name,
            controls=sliders if controls is None else controls,
            rest_vertices=model.mesh.vertices,
            faces=model.mesh.faces,
            joint_vertices=model.landmarks,
            joint_names=list(LANDMARKS),
            description=description,
            face_colors=model.mesh.face_colors,
            chunk=chunk,
        )
        self.model = model
        self.landmark_names = list(LANDMARKS)
        self.landmark_vertices = model.landmarks
        #: the face's own sliders and jaw, in the order ``_deform_face`` reads them
        self.face_control_names = names = [control.name for control in sliders]
        self._shape_columns = [names.index(n) for n in model.shapes.names]
        self._jaw_columns = {n: names.index(n) for n in ("jaw.rx", "jaw.ry", "jaw.tz")}

    def _deform(self, Y: torch.Tensor, vertex_index) -> DeformedMesh:
        return self._deform_face(Y, vertex_index)

    def _deform_face(self, Y: torch.Tensor, vertex_index) -> DeformedMesh:
        """The mesh for ``Y`` in :func:`face_controls`' order (a face driven by other
        controls maps them to these first: :mod:`rigmap.rigs.characters.arkit_face`)."""
        model, dtype, n = self.model, Y.dtype, Y.shape[0]
        jaw = {name: Y[:, column] for name, column in self._jaw_columns.items()}
        subset = slice(None) if vertex_index is None else np.asarray(vertex_index)
        if vertex_index is None:
            key = "all"
        elif np.array_equal(vertex_index, self.joint_vertices):
            key = "landmarks"
        else:
            key = None  # some other subset: convert without caching

        def const(name: str, array) -> torch.Tensor:
            if key is None:
                return torch.as_tensor(np.asarray(array, dtype=np.float64), dtype=dtype)
            return self.constant(f"{name}.{key}", array, dtype)

        weights = model.shapes.clamp(Y[:, self._shape_columns])
        jaw_open = clamp_between(jaw["jaw.rx"] / JAW_OPEN_FULL, 0.0, 1.0)
        drivers = torch.cat([weights, jaw_open[:, None]], dim=1)
        corrective = model.correctives.weights(drivers)

        rest = const("rest", self.rest_vertices[subset])
        vertices = (
            rest
            + model.shapes.offsets(weights, const("deltas", model.shapes.deltas[:, subset]))
            + model.shapes.offsets(corrective, const("corr", model.correctives.deltas[:, subset]))
        )

        # the jaw: open (rx) then side (ry) about the hinge, then forward (tz, cm)
        R = axis_rotation(jaw["jaw.ry"], "y") @ axis_rotation(jaw["jaw.rx"], "x")
        pivot = torch.as_tensor(JAW_PIVOT, dtype=dtype)
        forward = torch.stack(
            [torch.zeros_like(jaw_open), torch.zeros_like(jaw_open), jaw["jaw.tz"]], 1
        )
        t = pivot - (R @ pivot) + forward
        jawed = vertices @ R.transpose(1, 2) + t[:, None, :]
        w = const("jaw_weights", model.jaw_weights[subset])[None, :, None]
        vertices = vertices + w * (jawed - vertices)

        cog = torch.as_tensor(COG, dtype=dtype).expand(n, 3)
        rotation = torch.eye(3, dtype=dtype).expand(n, 3, 3)
        return DeformedMesh(vertices, cog, rotation)


# --- controls ---------------------------------------------------------------------
SLIDER_GROUPS = {
    "brows": ["brow_inner_up", "brow_outer_up", "brow_down", "brow_squeeze"],
    "eyes": ["eye_blink", "eye_wide", "eye_squint"],
    "cheeks": ["cheek_raise", "cheek_puff", "cheek_suck"],
    "nose": ["nose_wrinkle", "nostril_flare"],
    "mouth": [
        "mouth_smile",
        "mouth_frown",
        "mouth_stretch",
        "mouth_dimple",
        "mouth_press",
        "upper_lip_raise",
        "lower_lip_depress",
    ],
}
MOUTH_CENTER_SLIDERS = [
    "mouth_pucker",
    "mouth_funnel",
    "mouth_roll_upper",
    "mouth_roll_lower",
    "mouth_shrug_upper",
    "mouth_shrug_lower",
    "mouth_close",
    "mouth_shift",
]


def face_controls(shapes: Blendshapes) -> list[Control]:
    """49 controls: 46 sliders (their clamp range is their soft range) and the jaw."""
    group_of = {}
    for group, names in SLIDER_GROUPS.items():
        for name in names:
            group_of[f"{name}_l"] = group_of[f"{name}_r"] = group
    for name in MOUTH_CENTER_SLIDERS:
        group_of[name] = "mouth"
    controls = [
        Control(name, "scalar", 0.0, float(lo), float(hi), True, group_of[name])
        for name, lo, hi in zip(shapes.names, shapes.lower, shapes.upper, strict=True)
    ]
    controls += [
        Control("jaw.rx", "rotate", 0.0, -0.05, 0.45, True, "jaw"),
        Control("jaw.ry", "rotate", 0.0, -0.15, 0.15, True, "jaw"),
        Control("jaw.tz", "translate", 0.0, -0.4, 0.6, True, "jaw"),
    ]
    return controls


# --- the head mesh -------------------------------------------------------------------
def build_face_model() -> FaceModel:
    mesh, base = _head_mesh()
    # slide and push along the smooth head's normals: the creases (mouth slit, lids) would
    # otherwise turn a sideways slide into a push
    sculpt = Sculptor(mesh.vertices, vertex_normals(base, mesh.faces), base)
    shapes = Blendshapes(_slider_shapes(sculpt), mesh.n_vertices)
    correctives = CombinationShapes(
        _corrective_shapes(sculpt), [*shapes.names, "jaw_open"], mesh.n_vertices
    )
    landmarks = np.array([_nearest_front_vertex(base, xy) for xy in LANDMARKS.values()])
    return FaceModel(mesh, shapes, correctives, _jaw_weights(base), landmarks)


def _row_heights() -> np.ndarray:
    """Polar angles of the rings: even steps on the crown and under the chin, even
    *heights* over the face, and extra rings packed around the mouth slit."""
    b = HEAD_RADII[1]
    top, bottom = np.arccos(5.5 / b), np.arccos(-9.0 / b)
    face_y = np.arange(5.5, -9.0, -0.42)
    face_y = face_y[(np.abs(face_y - MOUTH_Y) > 0.62) & ((face_y < 0.2) | (face_y > 2.1))]
    eye_y = np.arange(2.1, 0.2, -0.19)
    mouth_y = MOUTH_Y + np.array([0.55, 0.32, 0.14, 0.0, -0.14, -0.32, -0.55])
    face_theta = np.arccos(np.concatenate([face_y, eye_y, mouth_y]) / b)
    crown = np.linspace(0, top, 8)[1:-1]
    chin = np.linspace(bottom, np.pi, 6)[1:-1]
    return np.unique(np.concatenate([crown, [top], face_theta, [bottom], chin]))


def _column_angles(cols: int = 60) -> np.ndarray:
    """Azimuths, three times denser at the front (phi = 0) than at the back."""
    s = -1.0 + 2.0 * np.arange(cols) / cols
    return np.pi * (0.35 * s + 0.65 * s**3)


def _base_point(theta, phi):
    """The head before features: an ellipsoid with a narrower jaw and flatter face."""
    a, b, c = HEAD_RADII
    theta, phi = np.broadcast_arrays(theta, phi)
    x = a * np.sin(theta) * np.sin(phi)
    y = b * np.cos(theta)
    z = c * np.sin(theta) * np.cos(phi)
    jaw = smoothstep(-1.0, -9.0, y)
    x = x * (1 - 0.2 * jaw)
    z = z * (1 - 0.06 * jaw) - 0.5 * smoothstep(-6.0, -10.5, y) * (z > 0)
    return np.stack([x, y, z], axis=-1)


def _head_mesh() -> tuple[TriangleMesh, np.ndarray]:
    thetas = _row_heights()
    phis = _column_angles()
    rings = _base_point(thetas[:, None], phis[None, :]).reshape(-1, 3)
    poles = _base_point(np.array([0.0, np.pi]), np.zeros(2))
    base = np.concatenate([poles[:1], rings, poles[1:]])
    grid = closed_grid(base, len(thetas), len(phis))
    normals = vertex_normals(base, grid.faces)
    vertices = base + normals * _feature_heights(base)[:, None]
    faces = grid.faces
    colors = _face_colors(base, faces, thetas, phis)
    mesh = TriangleMesh(
        vertices,
        faces,
        {"head": np.arange(len(vertices))},
        {"head": np.arange(len(faces))},
        colors,
    )
    return mesh, base


def _front(base: np.ndarray) -> np.ndarray:
    return smoothstep(0.05, 0.45, base[:, 2] / HEAD_RADII[2])


def _eye_opening(x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the left eye: (inside-almond parameter u in [-1, 1], upper lid y, lower lid y)."""
    u = (x - EYE[0]) / EYE_HALF_WIDTH
    span = np.sqrt(np.clip(1 - u * u, 0, 1))
    upper = EYE[1] + EYE_UPPER * span * (1 + 0.12 * u)
    lower = EYE[1] - EYE_LOWER * span
    return u, upper, lower


def _feature_heights(base: np.ndarray) -> np.ndarray:
    """Outward offsets (cm) that turn the ellipsoid into a face."""
    x, y = base[:, 0], base[:, 1]
    ax = np.abs(x)
    p = np.stack([ax, y], axis=1)  # features are mirror-symmetric
    h = np.zeros(len(base))
    # brow ridge and glabella
    h += 0.55 * gaussian_bump(p, (3.0, 2.95), (1.9, 0.55))
    h += 0.35 * gaussian_bump(p, (0.0, 2.5), (1.0, 0.7))
    # eye sockets, eyeballs and lid rims
    h -= 1.05 * gaussian_bump(p, EYE, (1.7, 1.25))
    eyeball = np.clip(1 - ((ax - EYE[0]) / 1.55) ** 2 - ((y - EYE[1]) / 1.05) ** 2, 0, None)
    h += 0.85 * np.sqrt(eyeball)
    u, upper, lower = _eye_opening(ax, y)
    rim = np.exp(-0.5 * ((y - upper) / 0.12) ** 2) * (y >= EYE[1]) + 0.6 * np.exp(
        -0.5 * ((y - lower) / 0.12) ** 2
    ) * (y < EYE[1])
    h += 0.18 * rim * smoothstep(1.15, 0.85, np.abs(u))
    # nose: bridge to tip, nostril wings, columella
    t = np.clip((1.9 - y) / 3.6, 0, 1)  # 0 at the bridge, 1 at the tip (y = -1.7)
    ridge = (0.35 + 2.3 * t**1.6) * smoothstep(-2.6, -1.6, y)
    width = 0.5 + 0.45 * t
    h += ridge * np.exp(-0.5 * (x / width) ** 2) * (y < 2.2) * smoothstep(2.2, 1.6, y)
    h += 0.95 * gaussian_bump(p, (1.05, -2.05), (0.55, 0.5))
    h += 0.5 * gaussian_bump(p, (0.0, -2.4), (0.45, 0.35))
    # cheeks and cheekbones, nasolabial fold
    h += 0.6 * gaussian_bump(p, (3.9, -1.6), (1.6, 1.7))
    h += 0.35 * gaussian_bump(p, (4.6, 0.1), (1.2, 0.8))
    h -= 0.18 * gaussian_bump(p, (2.3, -3.0), (0.3, 0.9))
    # lips, the slit between them, philtrum, chin
    lip_span = smoothstep(MOUTH_HALF_WIDTH + 0.2, MOUTH_HALF_WIDTH - 0.6, ax)
    h += 0.55 * gaussian_bump(p, (0.0, -3.72), (1.7, 0.32)) * (y > MOUTH_Y)
    h += 0.65 * gaussian_bump(p, (0.0, -4.72), (1.55, 0.38)) * (y <= MOUTH_Y)
    h -= 1.1 * np.exp(-0.5 * ((y - MOUTH_Y) / 0.11) ** 2) * lip_span
    h -= 0.12 * gaussian_bump(p, (0.0, -3.1), (0.25, 0.4))
    h -= 0.3 * gaussian_bump(p, (0.0, -5.6), (1.4, 0.35))
    h += 0.75 * gaussian_bump(p, (0.0, -7.0), (1.8, 1.0))
    h = h * _front(base)
    # ears on the sides
    h += 1.4 * _ear_mask(base)
    return h


def _ear_mask(base: np.ndarray) -> np.ndarray:
    side = smoothstep(0.8, 0.98, np.abs(base[:, 0]) / HEAD_RADII[0])
    return side * gaussian_bump(base, (0.0, 0.2, -1.0), (None, 1.7, 0.9))


def _face_colors(base: np.ndarray, faces: np.ndarray, thetas, phis) -> np.ndarray:
    centroid = base[faces].mean(axis=1)
    x, y, z = centroid[:, 0], centroid[:, 1], centroid[:, 2]
    ax = np.abs(x)
    front = z > 2.0
    colors = np.tile(COLOURS["skin"], (len(faces), 1))
    # hair on the crown and the back of the head; its edges follow grid rings and
    # columns so whole quads change colour (no saw-tooth)
    ring_y = HEAD_RADII[1] * np.cos(thetas)
    hairline = ring_y[np.argmin(np.abs(ring_y - 6.3))]
    nape = ring_y[np.argmin(np.abs(ring_y + 1.5))]
    column = np.abs(phis)[np.argmin(np.abs(np.abs(phis) - np.radians(112)))]
    back = np.arctan2(HEAD_RADII[0] * np.sin(column), HEAD_RADII[2] * np.cos(column))
    azimuth = np.abs(np.arctan2(x, z))
    hair = (y > hairline) | ((azimuth > back) & (y > nape))
    colors[hair] = COLOURS["hair"]
    # brows: a band over the brow ridge
    brow_center = 3.05 - 0.12 * (ax - 3.0) ** 2
    brows = front & (np.abs(y - brow_center) < 0.28) & (ax > 0.9) & (ax < 4.8)
    colors[brows] = COLOURS["brows"]
    # eyes: white almond, iris, pupil
    u, upper, lower = _eye_opening(ax, y)
    eye = front & (np.abs(u) < 1) & (y < upper) & (y > lower)
    colors[eye] = COLOURS["eye_white"]
    r = np.hypot(ax - EYE[0], y - EYE[1] + 0.05)
    colors[eye & (r < 0.5)] = COLOURS["iris"]
    colors[eye & (r < 0.24)] = COLOURS["pupil"]
    # lips and the inside of the mouth
    dy = y - MOUTH_Y
    lip_outline = (
        MOUTH_HALF_WIDTH
        * np.sqrt(np.clip(1 - np.where(dy > 0, dy / 0.9, -dy / 1.0) ** 2, 0, 1))
        * (1 + 0.08 * np.where(dy > 0, 1, -1))
    )
    lips = front & (ax < lip_outline) & (dy < 0.85) & (dy > -1.0)
    colors[lips] = COLOURS["lips"]
    colors[front & (np.abs(dy) < 0.145) & (ax < MOUTH_HALF_WIDTH - 0.15)] = COLOURS["mouth_inside"]
    return colors


def _nearest_front_vertex(base: np.ndarray, xy) -> int:
    front = np.flatnonzero(base[:, 2] > 0.5 * HEAD_RADII[2])
    d = np.hypot(base[front, 0] - xy[0], base[front, 1] - xy[1])
    return int(front[np.argmin(d)])


def _jaw_weights(base: np.ndarray) -> np.ndarray:
    """The lower face follows the jaw: sharply at the lips, softly on the cheeks, not behind
    the hinge."""
    x, y, z = base[:, 0], base[:, 1], base[:, 2]
    sharp = smoothstep(MOUTH_Y + 0.08, MOUTH_Y - 0.08, y)
    soft = smoothstep(MOUTH_Y + 1.4, MOUTH_Y - 2.2, y)
    lips = smoothstep(MOUTH_HALF_WIDTH + 0.9, MOUTH_HALF_WIDTH - 0.3, np.abs(x))
    weight = lips * sharp + (1 - lips) * soft
    return weight * smoothstep(-4.5, -1.0, z)


# --- sculpting ----------------------------------------------------------------------
Field = Callable[["Sculptor"], np.ndarray]


class Sculptor:
    """Builds offset fields on the face in face coordinates (x, y of the rest head, cm).

    A field is written for the character's left side (x > 0); ``mirrored``
    evaluates it on the reflected face for the right side.
    """

    def __init__(self, vertices: np.ndarray, normals: np.ndarray, base: np.ndarray, sign=1.0):
        self.vertices, self.normals, self.base, self.sign = vertices, normals, base, sign
        reflect = np.array([sign, 1.0, 1.0])
        self.p = base[:, :2] * reflect[:2]  # face coordinates, x mirrored for the right side
        self.x, self.y = self.p[:, 0], self.p[:, 1]
        self.front = _front(base)
        self._reflect = reflect

    def mirrored(self) -> Sculptor:
        return Sculptor(self.vertices, self.normals, self.base, -self.sign)

    def bump(self, center, radii) -> np.ndarray:
        return gaussian_bump(self.p, center, radii) * self.front

    def slide(self, dx, dy) -> np.ndarray:
        """Offsets that move skin across the surface by (dx, dy) cm (tangent projection)."""
        dx = np.broadcast_to(dx, self.x.shape) * self.sign
        dy = np.broadcast_to(dy, self.x.shape)
        t = np.stack([dx, dy, np.zeros_like(dx)], axis=1)
        return t - (t * self.normals).sum(1, keepdims=True) * self.normals

    def push(self, dh) -> np.ndarray:
        """Offsets along the outward normal (cm)."""
        return np.broadcast_to(dh, self.x.shape)[:, None] * self.normals

    def above_mouth(self) -> np.ndarray:
        return smoothstep(MOUTH_Y - 0.05, MOUTH_Y + 0.1, self.y)

    def below_mouth(self) -> np.ndarray:
        return 1.0 - self.above_mouth()


def _sided(name: str, field: Field, sculpt: Sculptor) -> list[ShapeSpec]:
    return [
        ShapeSpec(f"{name}_l", field(sculpt)),
        ShapeSpec(f"{name}_r", field(sculpt.mirrored())),
    ]


def _lid_fields(s: Sculptor, closing: float, opening: float, lower_raise: float) -> np.ndarray:
    """Lids: ``closing`` of the way shut (upper lid down), ``opening`` cm wider, lower lid up."""
    u, upper, lower = _eye_opening(s.x, s.y)
    inside = np.abs(u) < 1
    height = np.where(inside, upper - lower, 0.0)
    dy = np.zeros_like(s.y)
    # upper half: the opening compresses towards the lower lid, lid skin above follows
    target = lower + (1 - closing) * height  # where the upper lid edge goes
    in_opening = inside & (s.y >= lower) & (s.y <= upper)
    fraction = np.where(height > 0, (s.y - lower) / np.maximum(height, 1e-9), 0)
    dy += np.where(in_opening, fraction * (target - upper + opening), 0)
    above = inside & (s.y > upper)
    dy += np.where(above, (target - upper + opening) * smoothstep(1.3, 0.0, s.y - upper), 0)
    # lower lid rises (squint): the opening compresses from below, skin below follows
    if lower_raise:
        rise = lower_raise * height
        dy += np.where(in_opening, (1 - fraction) * rise, 0)
        below = inside & (s.y < lower)
        dy += np.where(below, rise * smoothstep(1.0, 0.0, lower - s.y), 0)
    dy = dy * s.front  # continuous at the eye corners: the opening's height goes to 0 there
    return s.slide(0.0, dy) + s.push(0.12 * np.abs(dy) * (s.y > lower))


def _slider_shapes(s: Sculptor) -> list[ShapeSpec]:
    shapes: list[ShapeSpec] = []
    shapes += _sided(
        "brow_inner_up",
        lambda t: (
            t.slide(0, 0.9 * t.bump((1.2, 3.0), (1.2, 1.5)))
            + t.push(0.1 * t.bump((1.0, 3.4), (1.0, 1.0)))
        ),
        s,
    )
    shapes += _sided("brow_outer_up", lambda t: t.slide(0, 0.8 * t.bump((4.2, 2.9), (1.3, 1.5))), s)
    shapes += _sided(
        "brow_down",
        lambda t: (
            t.slide(0.12 * t.bump((2.6, 2.9), (1.8, 1.0)), -0.6 * t.bump((2.7, 2.9), (2.1, 1.1)))
            + t.push(0.15 * t.bump((2.5, 2.8), (1.6, 0.8)))
        ),
        s,
    )
    shapes += _sided(
        "brow_squeeze",
        lambda t: (
            t.slide(-0.45 * t.bump((1.5, 2.7), (1.1, 0.9)), -0.15 * t.bump((1.5, 2.7), (1.1, 0.9)))
            + t.push(0.12 * t.bump((1.0, 2.6), (0.6, 0.6)))
        ),
        s,
    )
    shapes += _sided("eye_blink", lambda t: _lid_fields(t, 0.97, 0.0, 0.0), s)
    shapes += _sided("eye_wide", lambda t: _lid_fields(t, 0.0, 0.35, 0.0), s)
    shapes += _sided(
        "eye_squint",
        lambda t: (
            _lid_fields(t, 0.15, 0.0, 0.4) + t.slide(0, 0.2 * t.bump((3.3, -0.2), (1.3, 0.7)))
        ),
        s,
    )
    shapes += _sided(
        "cheek_raise",
        lambda t: (
            t.slide(0.1 * t.bump((3.7, -1.3), (1.5, 1.3)), 0.55 * t.bump((3.7, -1.3), (1.5, 1.3)))
            + t.push(0.3 * t.bump((3.7, -1.0), (1.3, 1.1)))
        ),
        s,
    )
    shapes += _sided("cheek_puff", lambda t: t.push(1.1 * t.bump((3.5, -4.0), (1.5, 1.5))), s)
    shapes += _sided("cheek_suck", lambda t: t.push(-0.7 * t.bump((3.7, -3.5), (1.1, 1.2))), s)
    shapes += _sided(
        "nose_wrinkle",
        lambda t: (
            t.slide(
                0, 0.4 * t.bump((1.1, -1.5), (0.8, 1.0)) + 0.3 * t.bump((1.2, -3.5), (0.7, 0.45))
            )
            + t.push(0.15 * t.bump((0.9, 0.0), (0.5, 0.8)))
        ),
        s,
    )
    shapes += _sided(
        "nostril_flare",
        lambda t: (
            t.slide(0.3 * t.bump((1.15, -2.05), (0.5, 0.5)), 0)
            + t.push(0.15 * t.bump((1.15, -2.05), (0.5, 0.5)))
        ),
        s,
    )
    corner = (MOUTH_HALF_WIDTH, MOUTH_Y)
    shapes += _sided(
        "mouth_smile",
        lambda t: (
            t.slide(0.55 * t.bump(corner, (1.2, 0.9)), 0.8 * t.bump(corner, (1.2, 0.9)))
            + t.push(0.25 * t.bump((3.2, -3.2), (0.9, 0.9)))
        ),
        s,
    )
    shapes += _sided(
        "mouth_frown",
        lambda t: t.slide(0.1 * t.bump(corner, (1.0, 0.8)), -0.65 * t.bump(corner, (1.1, 0.8))),
        s,
    )
    shapes += _sided(
        "mouth_stretch",
        lambda t: t.slide(0.75 * t.bump(corner, (1.4, 0.8)), -0.1 * t.bump(corner, (1.4, 0.8))),
        s,
    )
    shapes += _sided(
        "mouth_dimple",
        lambda t: (
            t.slide(0.3 * t.bump(corner, (1.0, 0.7)), 0)
            + t.push(-0.3 * t.bump((2.95, MOUTH_Y), (0.55, 0.55)))
        ),
        s,
    )
    shapes += _sided(
        "mouth_press",
        lambda t: (
            t.slide(0, -0.22 * np.tanh((t.y - MOUTH_Y) / 0.3) * t.bump((1.2, MOUTH_Y), (1.5, 0.8)))
            + t.push(-0.15 * t.bump((1.2, MOUTH_Y), (1.4, 0.7)))
        ),
        s,
    )
    shapes += _sided(
        "upper_lip_raise",
        lambda t: t.slide(0, 0.5 * t.bump((1.2, -3.7), (1.0, 0.6)) * t.above_mouth()),
        s,
    )
    shapes += _sided(
        "lower_lip_depress",
        lambda t: t.slide(0, -0.55 * t.bump((1.2, -4.8), (1.0, 0.7)) * t.below_mouth()),
        s,
    )
    lips = (0.0, MOUTH_Y)
    shapes += [
        ShapeSpec(
            "mouth_pucker",
            s.slide(-0.35 * s.x / MOUTH_HALF_WIDTH * s.bump(lips, (2.8, 1.2)), 0)
            + s.push(0.65 * s.bump(lips, (1.6, 0.9))),
        ),
        ShapeSpec(
            "mouth_funnel",
            s.slide(
                -0.15 * s.x / MOUTH_HALF_WIDTH * s.bump(lips, (2.8, 1.2)),
                0.25 * np.tanh((s.y - MOUTH_Y) / 0.25) * s.bump(lips, (1.7, 1.0)),
            )
            + s.push(0.5 * s.bump(lips, (1.8, 1.0))),
        ),
        ShapeSpec(
            "mouth_roll_upper",
            s.slide(0, -0.12 * s.bump((0, -3.8), (2.0, 0.4)))
            + s.push(-0.45 * s.bump((0, -3.8), (2.0, 0.35)) * s.above_mouth()),
        ),
        ShapeSpec(
            "mouth_roll_lower",
            s.slide(0, 0.12 * s.bump((0, -4.65), (1.9, 0.4)))
            + s.push(-0.45 * s.bump((0, -4.65), (1.9, 0.4)) * s.below_mouth()),
        ),
        ShapeSpec(
            "mouth_shrug_upper",
            s.slide(0, 0.3 * s.bump((0, -3.6), (2.1, 0.7)))
            + s.push(0.18 * s.bump((0, -3.6), (2.1, 0.6))),
        ),
        ShapeSpec(
            "mouth_shrug_lower",
            s.slide(0, 0.4 * s.bump((0, -5.6), (2.1, 1.4)))
            + s.push(0.2 * s.bump((0, -5.4), (1.8, 1.0))),
        ),
        ShapeSpec(
            "mouth_close", s.slide(0, 0.55 * s.bump((0, -4.6), (2.3, 0.6)) * s.below_mouth())
        ),
        ShapeSpec("mouth_shift", s.slide(0.6 * s.bump(lips, (3.0, 1.1)), 0), lower=-1.0, upper=1.0),
    ]
    return shapes


def _corrective_shapes(s: Sculptor) -> list[CombinationSpec]:
    def smile_open(t: Sculptor) -> np.ndarray:
        corner = (MOUTH_HALF_WIDTH, MOUTH_Y - 0.2)
        return t.slide(
            0.25 * t.bump(corner, (1.0, 0.9)), 0.3 * t.bump(corner, (1.0, 0.9))
        ) + t.push(-0.2 * t.bump(corner, (0.8, 0.8)))

    def smile_cheek(t: Sculptor) -> np.ndarray:
        return t.slide(0, 0.25 * t.bump((3.3, -0.3), (1.2, 0.8))) + t.push(
            0.2 * t.bump((3.6, -1.6), (1.2, 1.0))
        )

    lips = (0.0, MOUTH_Y)
    return [
        CombinationSpec("smile_open_l", ("jaw_open", "mouth_smile_l"), smile_open(s)),
        CombinationSpec("smile_open_r", ("jaw_open", "mouth_smile_r"), smile_open(s.mirrored())),
        CombinationSpec("smile_cheek_l", ("mouth_smile_l", "cheek_raise_l"), smile_cheek(s)),
        CombinationSpec(
            "smile_cheek_r", ("mouth_smile_r", "cheek_raise_r"), smile_cheek(s.mirrored())
        ),
        CombinationSpec(
            "brows_inner_up",
            ("brow_inner_up_l", "brow_inner_up_r"),
            s.slide(0, 0.3 * s.bump((0.0, 3.4), (1.2, 1.3)))
            + s.push(0.12 * s.bump((0.0, 3.6), (1.5, 1.0))),
        ),
        CombinationSpec(
            "pucker_open",
            ("jaw_open", "mouth_pucker"),
            s.slide(0, -0.25 * np.tanh((s.y - MOUTH_Y) / 0.3) * s.bump(lips, (1.6, 0.9)))
            + s.push(0.3 * s.bump(lips, (1.5, 0.9))),
        ),
    ]
