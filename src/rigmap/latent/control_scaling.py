"""Scaling rig controls by their influence on the mesh (Bailey et al. 2016, §4.1, Eqs 1–3).

PCA on raw controls aligns its axes with controls that vary a lot but barely move the
surface. The paper scales each control about the training mean, ``z = W (p − p̄) + p̄``,
with ``w_i ≈ ‖∂e/∂p_i‖`` so that a unit step in ``z_i`` moves the mesh about one unit.
The norm is estimated by least squares over rig evaluations at ``p̄ + n σ_i`` for
``n ∈ {−2, −1, 1, 2}`` (``n = 0`` adds nothing to Eq 3's sum), which gives the closed
form ``w_i = Σ_n d_n |δ_n| / Σ_n δ_n²`` with ``d_n = ‖e(p̄) − e(p̄ + δ_n)‖``.

"The mesh" is every vertex for a mesh rig (a rig with a ``mesh(Y)`` method, such as the
face) and the joint positions otherwise. Steps are clipped to the control's soft range
[lower, upper] and the clipped step ``δ_n`` is what enters the fit, so a control whose
mean sits at a range end is still measured on the side it can move to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigmap.latent.errors import LatentInputError

STEPS = (-2.0, -1.0, 1.0, 2.0)  # Eq 3's n, without the zero step
CONSTANT_STEP_FRACTION = 0.1  # ours: a control constant in the set is probed at 10 % of its range


@dataclass(frozen=True)
class ControlScaling:
    """Per-model weights ``w`` and means ``p̄`` over the rig's used controls.

    ``weights`` are in mesh units per control unit (cm per radian, cm per slider unit);
    a zero weight marks a control that moves nothing, which unscaling leaves at its mean.
    """

    names: tuple[str, ...]
    weights: np.ndarray  # (C,)
    mean: np.ndarray  # (C,)
    lower: np.ndarray  # (C,)
    upper: np.ndarray  # (C,)

    def scale(self, P) -> np.ndarray:
        """Controls ``(N, C)`` → scaled controls ``z = W (p − p̄) + p̄``."""
        P = check_values(P, len(self.names), "controls")
        return (P - self.mean) * self.weights + self.mean

    def unscale(self, Z, *, clamp: bool = True) -> np.ndarray:
        """Scaled controls → controls, clamped to the soft ranges unless ``clamp=False``."""
        Z = check_values(Z, len(self.names), "scaled controls")
        safe = np.where(self.weights > 0, self.weights, 1.0)
        P = np.where(self.weights > 0, (Z - self.mean) / safe + self.mean, self.mean)
        return np.clip(P, self.lower, self.upper) if clamp else P


def surface(rig, Y_full) -> np.ndarray:
    """``(N, S, 3)`` points that stand for the character's surface: vertices if the rig
    has a mesh, joint positions otherwise (both relative to the COG)."""
    mesh = getattr(rig, "mesh", None)
    return np.asarray(mesh(Y_full) if callable(mesh) else rig.evaluate(Y_full), dtype=np.float64)


def fit_control_scaling(rig, P, *, steps=STEPS) -> ControlScaling:
    """Eq 3 for every used control of ``rig``, from a training set ``P`` ``(N, C_used)``
    of used-control values. One batched rig evaluation of ``1 + C·len(steps)`` poses."""
    used = rig.controls.used_indices
    names = tuple(rig.controls.names[i] for i in used)
    P = check_values(P, len(used), "controls")
    if len(P) < 2:
        raise LatentInputError(f"control scaling needs at least 2 frames, got {len(P)}")
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    mean = np.clip(P.mean(axis=0), lower, upper)
    sigma = P.std(axis=0)
    span = upper - lower
    sigma = np.where(sigma > 0, sigma, CONSTANT_STEP_FRACTION * span)
    steps = np.asarray(steps, dtype=np.float64)
    C, S = len(used), len(steps)
    probes = np.tile(mean, (C * S, 1)).reshape(C, S, C)
    target = np.clip(
        mean[:, None] + steps[None, :] * sigma[:, None], lower[:, None], upper[:, None]
    )
    idx = np.arange(C)
    probes[idx, :, idx] = target
    delta = target - mean[:, None]  # (C, S), after clipping
    batch = np.concatenate([mean[None], probes.reshape(C * S, C)])
    points = surface(rig, rig.expand_used(batch))
    moved = points[1:].reshape(C, S, -1) - points[0].reshape(1, 1, -1)
    d = np.linalg.norm(moved, axis=2)
    denom = (delta**2).sum(axis=1)
    weights = np.where(
        denom > 0, (d * np.abs(delta)).sum(axis=1) / np.where(denom > 0, denom, 1), 0
    )
    return ControlScaling(names, weights, mean, lower.copy(), upper.copy())


def check_values(P, n_columns: int, what: str) -> np.ndarray:
    P = np.asarray(P, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != n_columns:
        raise LatentInputError(f"{what}: expected shape (N, {n_columns}), got {P.shape}")
    bad = ~np.isfinite(P)
    if bad.any():
        row, col = map(int, np.argwhere(bad)[0])
        raise LatentInputError(
            f"{what}: {int(bad.sum())} non-finite values, first at frame {row}, column {col}"
        )
    return P
