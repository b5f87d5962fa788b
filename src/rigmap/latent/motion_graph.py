"""A motion-graph baseline for transitions (Kovar, Gleicher & Pighin 2002), as §6 compares.

Frames are points on the character's surface (mesh vertices, or joints), relative to
its centre of gravity; the face rig has no root motion, so Kovar's optimal 2-D
alignment of point clouds is the identity and is left out (ours). For clips ``A`` and
``B`` the windowed distance is ``D(i, j) = Σ_{m<k} ‖e(A_{i+m}) − e(B_{j+m})‖²`` over
the ``k`` frames a transition blends (12, as the paper blends its own); transition
points are the local minima of ``D`` (8-neighbourhood) below a threshold. A
transition from ``A_i`` to ``B_j`` plays ``A`` up to ``i − 1``, then ``k`` frames
blending ``A_{i+m}`` into ``B_{j+m}`` with Kovar's weights
``α(p) = 2((p+1)/k)³ − 3((p+1)/k)² + 1`` on ``A`` (linear blend of controls, ours: the
face's controls are sliders and angles, all blended linearly), then ``B`` from
``j + k``. :func:`largest_component` is the frames of the graph's largest strongly
connected component, Kovar's pruning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from rigmap.gp.distances import expanded_squared_distances
from rigmap.latent.control_scaling import surface
from rigmap.latent.errors import LatentInputError

WINDOW = 12  # frames: the paper's blend length


def surface_features(rig, P) -> np.ndarray:
    """``(F, 3S)`` surface points of used-control values ``P`` ``(F, C)``."""
    return surface(rig, rig.expand_used(np.asarray(P, dtype=np.float64))).reshape(len(P), -1)


def window_distance(FA, FB, window: int = WINDOW) -> np.ndarray:
    """``D`` ``(len(A) − k + 1, len(B) − k + 1)`` of per-frame features ``FA``, ``FB``."""
    FA, FB = np.asarray(FA, dtype=np.float64), np.asarray(FB, dtype=np.float64)
    if len(FA) < window or len(FB) < window:
        raise LatentInputError(
            f"clips of {len(FA)} and {len(FB)} frames are shorter than the {window}-frame window"
        )
    d2 = expanded_squared_distances(FA, FB)
    n, m = len(FA) - window + 1, len(FB) - window + 1
    D = np.zeros((n, m))
    for k in range(window):
        D += d2[k : k + n, k : k + m]
    return D


@dataclass(frozen=True)
class GraphTransition:
    source: str
    target: str
    i: int  # first blended frame of the source clip
    j: int  # first blended frame of the target clip
    distance: float  # D(i, j)


def local_minima(D, threshold: float) -> list[tuple[int, int, float]]:
    """``(i, j, D_ij)`` at the 8-neighbourhood local minima of ``D`` below ``threshold``,
    lowest first."""
    D = np.asarray(D, dtype=np.float64)
    padded = np.pad(D, 1, constant_values=np.inf)
    is_min = D < threshold
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                neighbour = padded[1 + di : 1 + di + D.shape[0], 1 + dj : 1 + dj + D.shape[1]]
                is_min &= D <= neighbour
    rows, cols = np.nonzero(is_min)
    found = sorted(zip(D[rows, cols], rows, cols, strict=True))
    return [(int(i), int(j), float(d)) for d, i, j in found]


def find_transitions(
    clips_a: dict, clips_b: dict, *, threshold: float, window: int = WINDOW
) -> list[GraphTransition]:
    """Transitions from every clip of ``clips_a`` to every clip of ``clips_b`` (name →
    per-frame features), lowest distance first."""
    out = []
    for name_a, FA in clips_a.items():
        for name_b, FB in clips_b.items():
            if name_a == name_b:
                continue
            D = window_distance(FA, FB, window)
            out += [
                GraphTransition(name_a, name_b, i, j, d) for i, j, d in local_minima(D, threshold)
            ]
    return sorted(out, key=lambda t: t.distance)


def kovar_weights(window: int = WINDOW) -> np.ndarray:
    """Kovar's blend weights on the outgoing clip, ``α(p)`` for ``p = 0..k−1`` (1 → 0)."""
    x = (np.arange(window) + 1.0) / window
    return 2 * x**3 - 3 * x**2 + 1


def blend_transition(PA, PB, i: int, j: int, window: int = WINDOW) -> tuple[np.ndarray, int]:
    """The played controls of ``A → B`` at ``(i, j)`` and the frame the blend starts."""
    PA, PB = np.asarray(PA, dtype=np.float64), np.asarray(PB, dtype=np.float64)
    if not (0 <= i <= len(PA) - window and 0 <= j <= len(PB) - window):
        raise LatentInputError(f"transition ({i}, {j}) leaves the clips for a {window}-frame blend")
    a = kovar_weights(window)[:, None]
    blended = a * PA[i : i + window] + (1.0 - a) * PB[j : j + window]
    return np.vstack([PA[:i], blended, PB[j + window :]]), i


def largest_component(lengths: dict, transitions: list[GraphTransition], window: int = WINDOW):
    """Frames ``{clip: boolean mask}`` in the largest strongly connected component of the
    graph whose nodes are frames, edges each frame to the next and every transition
    ``A_i → B_{j+k}`` (ours: frame-level nodes, so a dead end is pruned to the frame)."""
    names = list(lengths)
    offset = dict(zip(names, np.cumsum([0] + [lengths[n] for n in names])[:-1], strict=True))
    total = sum(lengths.values())
    rows, cols = [], []
    for name in names:
        start, n = offset[name], lengths[name]
        rows += list(range(start, start + n - 1))
        cols += list(range(start + 1, start + n))
    for t in transitions:
        end = min(t.j + window, lengths[t.target] - 1)
        rows.append(offset[t.source] + t.i)
        cols.append(offset[t.target] + end)
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(total, total)).tocsr()
    _, labels = connected_components(graph, directed=True, connection="strong")
    biggest = np.bincount(labels).argmax()
    keep = labels == biggest
    return {name: keep[offset[name] : offset[name] + lengths[name]] for name in names}
