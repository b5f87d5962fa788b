"""Inside/outside and distance of points to a closed triangle mesh (numpy).

Used to *measure* collisions, e.g. whether the squirrel's teeth are inside its
body: the generalised winding number (Jacobson et al. 2013) is ~1 inside a
closed, outward-wound surface and ~0 outside; the distance to the nearest
triangle (closest point, Ericson's regions) gives the clearance in cm.
"""

from __future__ import annotations

import numpy as np


def winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(P,)`` winding numbers of points w.r.t. a closed mesh (solid angles / 4 pi)."""
    a = vertices[faces[:, 0]][None] - points[:, None]
    b = vertices[faces[:, 1]][None] - points[:, None]
    c = vertices[faces[:, 2]][None] - points[:, None]
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    triple = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    denominator = (
        la * lb * lc
        + np.einsum("pfi,pfi->pf", a, b) * lc
        + np.einsum("pfi,pfi->pf", b, c) * la
        + np.einsum("pfi,pfi->pf", c, a) * lb
    )
    return 2.0 * np.arctan2(triple, denominator).sum(axis=1) / (4.0 * np.pi)


def distances_to_mesh(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``(P,)`` Euclidean distance (cm) from each point to the nearest triangle."""
    a = vertices[faces[:, 0]][None]
    b = vertices[faces[:, 1]][None]
    c = vertices[faces[:, 2]][None]
    p = points[:, None]
    closest = _closest_points_on_triangles(p, a, b, c)
    return np.linalg.norm(closest - p, axis=-1).min(axis=1)


def signed_distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Distance to the surface, negative for points inside (winding number > 1/2)."""
    inside = winding_numbers(points, vertices, faces) > 0.5
    return np.where(inside, -1.0, 1.0) * distances_to_mesh(points, vertices, faces)


def _closest_points_on_triangles(p, a, b, c):
    """Closest point on each triangle to each point, broadcasting ``(P, F, 3)``."""

    def dot(u, v):
        return np.einsum("...i,...i->...", u, v)

    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2

    denominator = va + vb + vc
    safe = np.where(np.abs(denominator) > 1e-30, denominator, 1.0)
    v = vb / safe
    w = vc / safe
    result = a + ab * v[..., None] + ac * w[..., None]  # inside the face region

    def choose(mask, value):
        nonlocal result
        result = np.where(mask[..., None], value, result)

    # edge regions (later assignments win over earlier, vertex regions last)
    t_bc = (d4 - d3) / np.where(np.abs((d4 - d3) + (d5 - d6)) > 1e-30, (d4 - d3) + (d5 - d6), 1.0)
    choose((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * t_bc[..., None])
    t_ac = d2 / np.where(np.abs(d2 - d6) > 1e-30, d2 - d6, 1.0)
    choose((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * t_ac[..., None])
    t_ab = d1 / np.where(np.abs(d1 - d3) > 1e-30, d1 - d3, 1.0)
    choose((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * t_ab[..., None])
    choose((d6 >= 0) & (d5 <= d6), np.broadcast_to(c, result.shape))
    choose((d3 >= 0) & (d4 <= d3), np.broadcast_to(b, result.shape))
    choose((d1 <= 0) & (d2 <= 0), np.broadcast_to(a, result.shape))
    return result
