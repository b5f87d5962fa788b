"""Procedural closed surfaces for the built-in mesh characters.

Every primitive here is a *closed grid*: a pole, ``rows`` rings of ``cols``
vertices, another pole — the topology of a UV sphere. An ellipsoid, a
superellipsoid (a rounded box) and a tube swept along a curve all share it, so
one face builder serves them and every part is watertight. Parts are collected
in a :class:`MeshAssembly` that remembers which vertices and faces belong to
which part (the squirrel's teeth, the face's lips) and what colour each face is.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class TriangleMesh:
    """Vertices ``(V, 3)`` (cm), triangles ``(F, 3)`` with outward winding, named parts."""

    vertices: np.ndarray
    faces: np.ndarray
    part_vertices: dict[str, np.ndarray] = field(default_factory=dict)
    part_faces: dict[str, np.ndarray] = field(default_factory=dict)
    face_colors: np.ndarray | None = None

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    def vertices_of(self, *parts: str) -> np.ndarray:
        return np.concatenate([self.part_vertices[p] for p in parts])

    def faces_of(self, *parts: str) -> np.ndarray:
        return np.concatenate([self.part_faces[p] for p in parts])


def closed_grid_faces(rows: int, cols: int) -> np.ndarray:
    """Triangles of pole + ``rows`` rings of ``cols`` + pole (vertex 0 is the first pole).

    Winding is counter-clockwise seen from outside when rings go from the first
    pole to the second and, seen from the first pole, columns turn clockwise
    (what :func:`surface_of_revolution` and :func:`swept_tube` produce).
    """
    if rows < 1 or cols < 3:
        raise ValueError(f"a closed grid needs rows >= 1 and cols >= 3, got {rows}, {cols}")
    first, last = 0, 1 + rows * cols

    def ring(r: int, c: np.ndarray) -> np.ndarray:
        return 1 + r * cols + (c % cols)

    c = np.arange(cols)
    tris = [np.stack([np.full(cols, first), ring(0, c), ring(0, c + 1)], axis=1)]
    for r in range(rows - 1):
        a, b = ring(r, c), ring(r, c + 1)
        d, e = ring(r + 1, c), ring(r + 1, c + 1)
        tris.append(np.stack([a, d, e], axis=1))
        tris.append(np.stack([a, e, b], axis=1))
    tris.append(np.stack([ring(rows - 1, c), np.full(cols, last), ring(rows - 1, c + 1)], axis=1))
    return np.concatenate(tris).astype(np.int64)


def closed_grid(poles_and_rings: np.ndarray, rows: int, cols: int) -> TriangleMesh:
    """A closed grid mesh from its vertices, winding fixed so normals point outward."""
    vertices = np.asarray(poles_and_rings, dtype=np.float64)
    if vertices.shape != (rows * cols + 2, 3):
        raise ValueError(
            f"closed grid of {rows} x {cols}: expected {rows * cols + 2} vertices, "
            f"got {vertices.shape}"
        )
    faces = closed_grid_faces(rows, cols)
    if signed_volume(vertices, faces) < 0:
        faces = faces[:, [0, 2, 1]]
    return TriangleMesh(vertices, faces)


def surface_of_revolution(
    point: Callable[[np.ndarray, np.ndarray], np.ndarray], thetas: np.ndarray, cols: int
) -> TriangleMesh:
    """Closed surface ``point(theta, phi)`` with poles at theta = 0 and pi.

    ``thetas`` are the rings' polar angles, strictly inside (0, pi); ``phi``
    runs over ``cols`` equal steps. ``point`` takes broadcastable arrays and
    returns ``(..., 3)``.
    """
    thetas = np.asarray(thetas, dtype=np.float64)
    if not (np.all(np.diff(thetas) > 0) and thetas[0] > 0 and thetas[-1] < np.pi):
        raise ValueError("ring angles must increase strictly inside (0, pi)")
    phis = np.arange(cols) * (2 * np.pi / cols)
    rings = point(thetas[:, None], phis[None, :]).reshape(-1, 3)
    poles = point(np.array([0.0, np.pi]), np.zeros(2))
    return closed_grid(np.concatenate([poles[:1], rings, poles[1:]]), len(thetas), cols)


def ellipsoid_point(center, radii, rotation=None):
    """``point(theta, phi)`` of an ellipsoid whose polar axis is local +y, phi = 0 at local +z."""
    center = np.asarray(center, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)

    def point(theta, phi):
        theta, phi = np.broadcast_arrays(theta, phi)
        local = np.stack(
            [
                radii[0] * np.sin(theta) * np.sin(phi),
                radii[1] * np.cos(theta),
                radii[2] * np.sin(theta) * np.cos(phi),
            ],
            axis=-1,
        )
        return local @ R.T + center

    return point


def superellipsoid_point(center, radii, exponent: float, rotation=None):
    """Like :func:`ellipsoid_point` with corners: exponent 1 is an ellipsoid, ~0.2 a rounded box."""
    center = np.asarray(center, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)

    def signed_power(x):
        return np.sign(x) * np.abs(x) ** exponent

    def point(theta, phi):
        theta, phi = np.broadcast_arrays(theta, phi)
        local = np.stack(
            [
                radii[0] * signed_power(np.sin(theta)) * signed_power(np.sin(phi)),
                radii[1] * signed_power(np.cos(theta)),
                radii[2] * signed_power(np.sin(theta)) * signed_power(np.cos(phi)),
            ],
            axis=-1,
        )
        return local @ R.T + center

    return point


def swept_tube(
    curve: np.ndarray,
    radii: np.ndarray,
    cols: int,
    *,
    up=(0.0, 1.0, 0.0),
    cap_extension: float = 0.5,
) -> TriangleMesh:
    """A closed tube along a polyline ``curve (R, 3)`` with ring radii ``(R,)`` or ``(R, 2)``.

    Rings lie in planes normal to the curve, oriented by rotation-minimising
    frames started from ``up``. Each end is closed by a pole pushed
    ``cap_extension`` x the end radius beyond the curve, so the ends are round.
    """
    curve = np.asarray(curve, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    if radii.ndim == 1:
        radii = np.stack([radii, radii], axis=1)
    if len(curve) != len(radii) or len(curve) < 2:
        raise ValueError(f"tube: {len(curve)} curve points but {len(radii)} radii (need >= 2)")
    tangents = np.gradient(curve, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    normals = _rotation_minimising_normals(tangents, np.asarray(up, dtype=np.float64))
    binormals = np.cross(tangents, normals)
    phis = np.arange(cols) * (2 * np.pi / cols)
    rings = (
        curve[:, None, :]
        + radii[:, 0, None, None] * np.cos(phis)[None, :, None] * normals[:, None, :]
        + radii[:, 1, None, None] * np.sin(phis)[None, :, None] * binormals[:, None, :]
    ).reshape(-1, 3)
    start = curve[0] - tangents[0] * cap_extension * radii[0].mean()
    end = curve[-1] + tangents[-1] * cap_extension * radii[-1].mean()
    return closed_grid(np.concatenate([start[None], rings, end[None]]), len(curve), cols)


def _rotation_minimising_normals(tangents: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Normals along a curve that twist as little as possible (double reflection)."""
    n = up - (up @ tangents[0]) * tangents[0]
    if np.linalg.norm(n) < 1e-6:
        n = np.cross(tangents[0], [1.0, 0.0, 0.0])
    normals = [n / np.linalg.norm(n)]
    for t0, t1 in itertools.pairwise(tangents):
        axis = np.cross(t0, t1)
        s = np.linalg.norm(axis)
        n = normals[-1]
        if s > 1e-9:
            axis /= s
            angle = np.arctan2(s, t0 @ t1)
            n = (
                n * np.cos(angle)
                + np.cross(axis, n) * np.sin(angle)
                + axis * (axis @ n) * (1 - np.cos(angle))
            )
        n = n - (n @ t1) * t1
        normals.append(n / np.linalg.norm(n))
    return np.array(normals)


def polyline_resample(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` points at equal arc length along a Catmull-Rom spline through ``points``."""
    points = np.asarray(points, dtype=np.float64)
    padded = np.concatenate([2 * points[:1] - points[1:2], points, 2 * points[-1:] - points[-2:-1]])
    dense = []
    for i in range(len(points) - 1):
        p0, p1, p2, p3 = padded[i : i + 4]
        t = np.linspace(0, 1, 32, endpoint=False)[:, None]
        dense.append(
            0.5
            * (
                2 * p1
                + (-p0 + p2) * t
                + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                + (-p0 + 3 * p1 - 3 * p2 + p3) * t**3
            )
        )
    dense.append(points[-1:])
    dense = np.concatenate(dense)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    targets = np.linspace(0, arc[-1], count)
    return np.stack([np.interp(targets, arc, dense[:, k]) for k in range(3)], axis=1)


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed mesh (cm³); negative when the winding points inward."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted face normals ``(..., F, 3)`` (length = twice the area)."""
    a = vertices[..., faces[:, 0], :]
    b = vertices[..., faces[:, 1], :]
    c = vertices[..., faces[:, 2], :]
    return np.cross(b - a, c - a)


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit vertex normals ``(V, 3)``, area-weighted average of the incident faces."""
    fn = face_normals(vertices, faces)
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], fn)
    length = np.linalg.norm(normals, axis=-1, keepdims=True)
    return normals / np.maximum(length, 1e-12)


class MeshAssembly:
    """Collects closed parts into one mesh, keeping per-part indices and face colours."""

    def __init__(self) -> None:
        self._parts: list[tuple[str, TriangleMesh, np.ndarray]] = []

    def add(self, name: str, part: TriangleMesh, color) -> None:
        """Add a part; ``color`` is one RGB triple or one per face ``(F, 3)``."""
        if any(name == existing for existing, _, _ in self._parts):
            raise ValueError(f"mesh part {name!r} added twice")
        colors = np.asarray(color, dtype=np.float64)
        if colors.ndim == 1:
            colors = np.tile(colors, (len(part.faces), 1))
        if colors.shape != (len(part.faces), 3):
            raise ValueError(
                f"mesh part {name!r}: colours must be (3,) or ({len(part.faces)}, 3), "
                f"got {colors.shape}"
            )
        self._parts.append((name, part, colors))

    def build(self) -> TriangleMesh:
        vertices, faces, colors = [], [], []
        part_vertices, part_faces = {}, {}
        v0 = f0 = 0
        for name, part, part_colors in self._parts:
            vertices.append(part.vertices)
            faces.append(part.faces + v0)
            colors.append(part_colors)
            part_vertices[name] = np.arange(v0, v0 + len(part.vertices))
            part_faces[name] = np.arange(f0, f0 + len(part.faces))
            v0 += len(part.vertices)
            f0 += len(part.faces)
        return TriangleMesh(
            np.concatenate(vertices),
            np.concatenate(faces),
            part_vertices,
            part_faces,
            np.concatenate(colors),
        )
