"""Rotations a retarget script solves for, batched over frames (numpy).

These are the maths behind Maya's aim and orient constraints: the smallest
rotation taking one direction onto another, a frame from a direction and a
plane, the best rotation carrying a rigid set of points (Kabsch), and aims
restricted to the one or two rotation channels a control actually exposes.
All angles are in radians and rotations act on column vectors.
"""

from __future__ import annotations

import numpy as np

AXES = "xyz"
_TINY = 1e-12


def unit(v: np.ndarray) -> np.ndarray:
    """Vectors scaled to length one (zero vectors stay zero)."""
    v = np.asarray(v, dtype=np.float64)
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(norm, _TINY)


def axis_vector(axis: str) -> np.ndarray:
    vector = np.zeros(3)
    vector[AXES.index(axis)] = 1.0
    return vector


def rotate(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(N, 3, 3) @ (N, 3)`` or ``(3,)`` vectors -> ``(N, 3)``."""
    v = np.broadcast_to(np.asarray(v, dtype=np.float64), R.shape[:-1])
    return np.einsum("...ij,...j->...i", R, v)


def rotate_back(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``Rᵀ v``: a world vector in the frame ``R`` (rotations only)."""
    v = np.broadcast_to(np.asarray(v, dtype=np.float64), R.shape[:-1])
    return np.einsum("...ji,...j->...i", R, v)


def axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: ``(N, 3)`` unit axes and ``(N,)`` angles -> ``(N, 3, 3)``."""
    x, y, z = np.moveaxis(axis, -1, 0)
    zero = np.zeros_like(x)
    K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=-1).reshape(*x.shape, 3, 3)
    s = np.sin(angle)[..., None, None]
    c = np.cos(angle)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def principal_rotation(angle: np.ndarray, axis: str) -> np.ndarray:
    """``(N,)`` angles about x, y or z -> ``(N, 3, 3)``."""
    angle = np.asarray(angle, dtype=np.float64)
    return axis_angle(np.broadcast_to(axis_vector(axis), (*angle.shape, 3)), angle)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction ``a`` onto direction ``b`` (``(N, 3, 3)``).

    Opposite directions turn half a revolution about any axis perpendicular to ``a``.
    """
    a, b = np.broadcast_arrays(unit(a), unit(b))
    cross = np.cross(a, b)
    sin = np.linalg.norm(cross, axis=-1)
    cos = np.sum(a * b, axis=-1)
    # a fallback axis perpendicular to a, for the antiparallel case
    helper = np.where(np.abs(a[..., :1]) < 0.9, axis_vector("x"), axis_vector("y"))
    fallback = unit(np.cross(a, helper))
    axis = np.where((sin > 1e-9)[..., None], cross / np.maximum(sin, _TINY)[..., None], fallback)
    return axis_angle(axis, np.arctan2(sin, cos))


def frame_from_plane(primary: np.ndarray, in_plane: np.ndarray) -> np.ndarray:
    """Right-handed frame: first column along ``primary``, third normal to the plane."""
    u = unit(primary)
    w = unit(np.cross(u, in_plane))
    v = np.cross(w, u)
    return np.stack([u, v, w], axis=-1)


def best_rotation(rest_vectors: np.ndarray, target_vectors: np.ndarray) -> np.ndarray:
    """Kabsch: the rotation ``R`` minimising ``Σ |R r_k − t_k|²``.

    ``rest_vectors`` ``(K, 3)``, ``target_vectors`` ``(N, K, 3)``; at least two
    non-parallel vectors are needed for a unique answer.
    """
    H = np.einsum("ki,nkj->nij", np.asarray(rest_vectors, float), target_vectors)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    d = np.where(d == 0, 1.0, d)
    D = np.zeros_like(H)
    D[:, 0, 0] = D[:, 1, 1] = 1.0
    D[:, 2, 2] = d
    return np.swapaxes(Vt, -1, -2) @ D @ np.swapaxes(U, -1, -2)


def orthonormalize(M: np.ndarray) -> np.ndarray:
    """Gram-Schmidt on the first two columns (the rig engine's convention)."""
    x = unit(M[..., :, 0])
    y = M[..., :, 1]
    y = unit(y - np.sum(y * x, axis=-1, keepdims=True) * x)
    return np.stack([x, y, np.cross(x, y)], axis=-1)


def angle_about(d0: np.ndarray, d1: np.ndarray, axis: str) -> np.ndarray:
    """Signed angle about ``axis`` that best turns direction ``d0`` towards ``d1``."""
    a = axis_vector(axis)
    d0, d1 = np.broadcast_arrays(np.asarray(d0, float), np.asarray(d1, float))
    p = d0 - np.sum(d0 * a, axis=-1, keepdims=True) * a
    q = d1 - np.sum(d1 * a, axis=-1, keepdims=True) * a
    return np.arctan2(np.sum(np.cross(p, q) * a, axis=-1), np.sum(p * q, axis=-1))


def two_axis_aim(
    d0: np.ndarray, d1: np.ndarray, inner: str, outer: str
) -> tuple[np.ndarray, np.ndarray]:
    """Angles ``(θ_inner, θ_outer)`` with ``R_outer(θ_outer) R_inner(θ_inner) d0 ∥ d1``.

    The outer rotation keeps the component along its axis, so the inner one
    must first give ``d0`` the component ``d1`` has there; of the two inner
    angles that do, the pair closer to zero is kept. A direction out of reach
    gets the closest reachable component.
    """
    a, b = axis_vector(outer), axis_vector(inner)
    v = unit(d0) * np.ones_like(np.asarray(d1, float))
    w = unit(d1)
    along_b = np.sum(v * b, axis=-1, keepdims=True) * b
    perp = v - along_b
    alpha = np.sum(perp * a, axis=-1)
    beta = np.sum(np.cross(b, v) * a, axis=-1)
    reach = np.hypot(alpha, beta)
    phase = np.arctan2(beta, alpha)
    ratio = np.where(reach > 1e-9, np.sum(w * a, axis=-1) / np.maximum(reach, _TINY), 0.0)
    spread = np.arccos(np.clip(ratio, -1.0, 1.0))
    best_inner = best_outer = best_cost = None
    for candidate in (phase + spread, phase - spread):
        inner_angle = np.where(reach > 1e-9, _wrap(candidate), 0.0)
        turned = rotate(principal_rotation(inner_angle, inner), v)
        outer_angle = angle_about(turned, w, outer)
        cost = inner_angle**2 + outer_angle**2
        if best_cost is None:
            best_inner, best_outer, best_cost = inner_angle, outer_angle, cost
        else:
            better = cost < best_cost
            best_inner = np.where(better, inner_angle, best_inner)
            best_outer = np.where(better, outer_angle, best_outer)
            best_cost = np.minimum(cost, best_cost)
    return best_inner, best_outer


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi
