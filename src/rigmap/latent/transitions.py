"""Matching points between latent models and routes through them (Bailey et al. 2016, §5.2).

For models ``M1``, ``M2``: every training latent point ``x1`` of ``M1`` gives a pose
``z1 = g(x1; M1)`` (Eq 8 → controls); ``z1`` is scaled and reduced by ``M2``'s own
scaling and PCA (Eq 13) and projected into ``M2``'s latent space,
``x2 = argmin_x ‖ŷ1 − k_xᵀ K⁻¹ Y2‖²`` (Eqs 14–15; Levenberg–Marquardt from the nearest
training output, :meth:`~rigmap.latent.GPLVM.project`). The pair is kept if the two
poses ``g(x1; M1)`` and ``g(x2; M2)`` are closer than a threshold. The paper measures
that distance in rig-control space; here (ours) it is measured where a viewer sees it,
on the surface: the largest distance between the two poses' points over the mesh
vertices (joints for a rig without a mesh), in the rig's unit (cm) — an RMS over a
whole head would be diluted by the vertices no expression moves. The control-space
distance is kept next to it.

Pairs of both directions serve a transition either way (a pair found from ``M2``'s
side is the same bridge read backwards). Two models with no pair are joined, if at
all, through others: :meth:`TransitionTable.route` is the fewest-hops path of models
(§7: happy → neutral → grumpy).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rigmap.latent.control_scaling import surface
from rigmap.latent.errors import LatentInputError

MATCH_THRESHOLD_CM = 0.1  # ours: largest vertex distance of a bridge's two poses (cm)
BLEND_FRAMES = 12  # the paper's average blend length (§6)


@dataclass
class MatchSet:
    """Bridges from ``source`` to ``target``: latent points in each, their surface
    distance (cm) and control-space distance."""

    source: str
    target: str
    source_points: np.ndarray  # (K, q)
    target_points: np.ndarray  # (K, q)
    distance_cm: np.ndarray  # (K,)
    control_distance: np.ndarray  # (K,)
    candidates: int = 0  # training points tried

    def __len__(self) -> int:
        return len(self.distance_cm)

    def reversed(self) -> MatchSet:
        return MatchSet(
            self.target,
            self.source,
            self.target_points,
            self.source_points,
            self.distance_cm,
            self.control_distance,
            self.candidates,
        )

    def spread(self) -> float:
        """RMS distance of the source points from their centroid (latent units; 0 if < 2)."""
        if len(self) < 2:
            return 0.0
        P = self.source_points
        return float(np.sqrt(((P - P.mean(0)) ** 2).sum(1).mean()))


def surface_distance(rig, P_a, P_b) -> np.ndarray:
    """Per frame, the largest ``‖e(a) − e(b)‖`` over surface points (rig units)."""
    a = surface(rig, rig.expand_used(P_a))
    b = surface(rig, rig.expand_used(P_b))
    return np.sqrt(((a - b) ** 2).sum(-1)).max(-1)


def match_pair(
    rig,
    source,
    target,
    *,
    names=("source", "target"),
    threshold_cm: float = MATCH_THRESHOLD_CM,
    max_iter: int = 100,
) -> MatchSet:
    """Bridges from every training latent point of ``source`` into ``target``."""
    X1 = source.latent
    P1 = source.to_controls(X1)
    X2 = target.project(P1, max_iter=max_iter)
    P2 = target.to_controls(X2)
    dist = surface_distance(rig, P1, P2)
    ctrl = np.sqrt(((P1 - P2) ** 2).sum(1))
    keep = dist < threshold_cm
    return MatchSet(names[0], names[1], X1[keep], X2[keep], dist[keep], ctrl[keep], len(X1))


@dataclass
class TransitionTable:
    """Bridges for every ordered pair of models (both directions merged)."""

    matches: dict[tuple[str, str], MatchSet]
    models: tuple[str, ...]
    threshold_cm: float

    def pair(self, a: str, b: str) -> MatchSet:
        self._check(a)
        self._check(b)
        return self.matches[(a, b)]

    def _check(self, name: str) -> None:
        if name not in self.models:
            raise LatentInputError(f"no model named {name!r}; models: {list(self.models)}")

    def neighbours(self, a: str) -> list[str]:
        return [b for b in self.models if b != a and len(self.matches[(a, b)]) > 0]

    def route(self, a: str, b: str) -> list[str]:
        """The fewest-hops list of models from ``a`` to ``b`` (both included) along pairs
        with at least one bridge; an error naming both if there is none."""
        self._check(a)
        self._check(b)
        if a == b:
            return [a]
        previous = {a: None}
        queue = deque([a])
        while queue:
            here = queue.popleft()
            for there in self.neighbours(here):
                if there not in previous:
                    previous[there] = here
                    if there == b:
                        path = [b]
                        while previous[path[-1]] is not None:
                            path.append(previous[path[-1]])
                        return path[::-1]
                    queue.append(there)
        raise LatentInputError(
            f"no transition from model {a!r} to {b!r}: no chain of models with matching "
            f"points joins them (threshold {self.threshold_cm} cm)"
        )

    def without(self, a: str, b: str) -> TransitionTable:
        """A copy with the bridges between ``a`` and ``b`` removed (both directions)."""
        matches = dict(self.matches)
        for key in ((a, b), (b, a)):
            m = matches[key]
            empty = np.zeros((0, m.source_points.shape[1]))
            matches[key] = MatchSet(
                m.source, m.target, empty, empty, np.zeros(0), np.zeros(0), m.candidates
            )
        return TransitionTable(matches, self.models, self.threshold_cm)

    def nearest(self, a: str, b: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """The bridge of ``(a, b)`` whose point in ``a`` is nearest ``x``:
        ``(x_a, x_b, distance_cm)``."""
        m = self.pair(a, b)
        if len(m) == 0:
            raise LatentInputError(f"models {a!r} and {b!r} share no matching point")
        k = int(((m.source_points - x) ** 2).sum(1).argmin())
        return m.source_points[k], m.target_points[k], float(m.distance_cm[k])


def match_models(
    rig, models: Mapping, *, threshold_cm: float = MATCH_THRESHOLD_CM, max_iter: int = 100
) -> TransitionTable:
    """Bridges between every pair of ``models`` (name → LatentModel)."""
    if not threshold_cm > 0:
        raise LatentInputError(f"match threshold must be > 0 cm, got {threshold_cm}")
    names = tuple(models)
    one_way = {}
    for a in names:
        for b in names:
            if a != b:
                one_way[(a, b)] = match_pair(
                    rig,
                    models[a],
                    models[b],
                    names=(a, b),
                    threshold_cm=threshold_cm,
                    max_iter=max_iter,
                )
    merged = {}
    for a, b in one_way:
        forward, backward = one_way[(a, b)], one_way[(b, a)].reversed()
        merged[(a, b)] = MatchSet(
            a,
            b,
            np.vstack([forward.source_points, backward.source_points]),
            np.vstack([forward.target_points, backward.target_points]),
            np.concatenate([forward.distance_cm, backward.distance_cm]),
            np.concatenate([forward.control_distance, backward.control_distance]),
            forward.candidates + backward.candidates,
        )
    return TransitionTable(merged, names, threshold_cm)


def blend_weights(frames: int = BLEND_FRAMES) -> np.ndarray:
    """Smoothstep weights ``3s² − 2s³`` of the incoming pose over a blend of ``frames``
    frames (ours: the paper does not give its blend curve), from just above 0 to 1."""
    if frames < 1:
        raise LatentInputError(f"blend frames must be ≥ 1, got {frames}")
    s = np.arange(1, frames + 1) / frames
    return 3 * s**2 - 2 * s**3
