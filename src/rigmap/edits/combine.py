"""The combined solve of §4.2–4.3 (Eqs 7–12): one banded SPD system per output.

For one output channel over a clip of ``F`` frames, with source values ``j`` and source
accelerations ``j̈ = L j`` (``L`` the second-difference operator, ``(F−2) × F``), the
kinematic GP's means ``μk`` and variances ``σk²`` and the acceleration GP's ``μa``,
``σa²``, the target ``Y`` minimises

    w_lk Σ (Y − μk)²/σk² + w_rk Σ σk²/pk² (Y − j)²
      + w_la Σ (LY − μa)²/σa² + w_ra Σ σa²/pa² (LY − j̈)²

— Eq. 12 with §4.3's choice ``Σ_rk⁻¹ ∝ Σ_lk`` and ``Σ_ra⁻¹ ∝ Σ_la``: where a prediction is
unsure, its regulariser toward the source is strong, so an unsure frame falls back to
the source.

§4.3 sets the regulariser precision *equal* to the variance, which is not unit-free: a
precision is 1/units², a variance units². With a GP's variance in training-std² the
equality makes the regulariser depend on how big the edit is: for an edit of 0.05 std
the GP's prior variance σ_f² + σ_n² is about 0.0025, so even a frame far from every
example (variance at the prior) gets regulariser precision 0.0025 against a kinematic
precision of 400, and the regulariser never acts (measured: the biped's full solve and
"both without regularisers" gave the same held-out edit error to three digits on all
four edits). The proportionality constant
§4.3 leaves open is taken here as ``1/p²``, ``p`` the predictor's prior variance
(``priors``; :attr:`rigmap.edits.gp.SharedGP.prior_variance`; ``pk``, ``pa`` above):
``Σ_r⁻¹ = Σ_l / p²``, in
the units of its own term, so a frame at the prior weighs its prediction and the source
equally (at weight 1) and a frame near the examples follows the prediction. ``priors =
(1, 1)`` is §4.3 as written. Measured on the biped's four edits (held-out edit error,
std²): arm_swing 2.69e-4 → 2.49e-4, arms_forward_walking 1.20e-3 → 8.8e-4, lean_back
5.9e-5 → 4.8e-5, half_steps_arms_forward 0.0168 → 0.0157.

Setting the gradient to zero gives ``(D_k + Lᵀ D_a L) Y = b``, pentadiagonal
(``L`` spans three frames), solved by :func:`scipy.linalg.solveh_banded`. The variances
are shared by all outputs of a predictor, so one factorisation serves every output; a
masked output (a joint the edit must not touch, §4.2's "restrict the edits to particular
joints") is the limit of an infinitely strong regulariser: the source itself.

Erratum: Eqs 11–12 say ``arg max`` of positive quadratic forms; the estimate is their
``arg min`` (the maximum of the log-posterior they come from).

The paper gives no values for the four weights (it tuned them by hand in "three
iterations"); the defaults here, all 1, are ours.

Variances below ``MIN_VARIANCE`` (1e-6 training-std², i.e. 0.001 std; value is ours)
are raised to it. A GP fitted to noiseless examples (the procedural edits) learns a
noise near 1e-8 and so predicts variances near 1e-16 where it has seen the motion; used
as they are, the kinematic precision (1e16) and its regulariser's (1e-16) differ by 32
orders of magnitude and the banded Cholesky fails ("leading minor not positive
definite") as soon as the kinematic weight is 0. No edit is specified to better than a
thousandth of a standard deviation, so the floor changes no result it can be told apart
by; it keeps every weight's term representable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded

from rigmap.errors import RigmapError

MIN_VARIANCE = 1e-6  # training-std²; ours (module docstring)


class CombineError(RigmapError, ValueError):
    """Predictions and source that do not line up; names the array and its shape."""


@dataclass(frozen=True)
class Weights:
    """``w_lk, w_rk, w_la, w_ra`` of Eq. 12 (kinematic, its regulariser, acceleration, its
    regulariser). Zero regulariser weights trust the GPs alone; zero GP weights copy the
    source (the paper's remark after Eq. 12)."""

    kinematic: float = 1.0
    kinematic_regularizer: float = 1.0
    acceleration: float = 1.0
    acceleration_regularizer: float = 1.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not (np.isfinite(value) and value >= 0):
                raise CombineError(f"weight {name} is {value}; weights must be finite and >= 0")


def second_difference(n_frames: int) -> np.ndarray:
    """Dense ``L`` (``(F−2) × F``): ``(LY)_i = Y_i − 2Y_{i+1} + Y_{i+2}`` (per frame²)."""
    L = np.zeros((max(n_frames - 2, 0), n_frames))
    for i in range(n_frames - 2):
        L[i, i : i + 3] = (1.0, -2.0, 1.0)
    return L


def accelerations(values: np.ndarray) -> np.ndarray:
    """``L`` applied along frames: ``(F, D)`` → ``(F−2, D)``."""
    values = np.asarray(values, dtype=np.float64)
    return values[:-2] - 2.0 * values[1:-1] + values[2:]


def combine(
    source: np.ndarray,
    kinematic_mean: np.ndarray,
    kinematic_variance: np.ndarray,
    acceleration_mean: np.ndarray,
    acceleration_variance: np.ndarray,
    weights: Weights = Weights(),
    *,
    masked: np.ndarray | None = None,
    priors: tuple[float, float] = (1.0, 1.0),
) -> np.ndarray:
    """The target ``(F, D)`` of Eq. 12 for every output of a clip (see the module docstring).

    ``source``, ``kinematic_mean``: ``(F, D)``; ``kinematic_variance``: ``(F,)``;
    ``acceleration_mean``: ``(F−2, D)``; ``acceleration_variance``: ``(F−2,)``;
    ``masked``: ``(D,)`` booleans, outputs kept at the source; ``priors``: the kinematic
    and acceleration predictors' prior variances (the regularisers' unit, module docstring).
    """
    j, mk, vk, ma, va = _checked(
        source, kinematic_mean, kinematic_variance, acceleration_mean, acceleration_variance
    )
    n_frames, n_out = j.shape
    w = weights
    rk, ra = _regularizer_precisions(vk, va, priors)
    diagonal_k = w.kinematic / vk + w.kinematic_regularizer * rk
    rhs = (w.kinematic / vk)[:, None] * mk + (w.kinematic_regularizer * rk)[:, None] * j
    diagonal_a = w.acceleration / va + w.acceleration_regularizer * ra
    target_a = (w.acceleration / va)[:, None] * ma + (w.acceleration_regularizer * ra)[:, None] * (
        accelerations(j)
    )
    rhs = rhs + _apply_lt(target_a, n_frames)
    bands = _upper_bands(diagonal_k, diagonal_a)
    if bands[-1].min() <= 0:
        raise CombineError("the combined system is singular: every weight on some frame is 0")
    solution = solveh_banded(bands, rhs)
    if masked is not None:
        masked = np.asarray(masked, dtype=bool)
        if masked.shape != (n_out,):
            raise CombineError(f"masked has shape {masked.shape}, expected ({n_out},)")
        solution[:, masked] = j[:, masked]
    return solution


def combine_dense(
    source,
    kinematic_mean,
    kinematic_variance,
    acceleration_mean,
    acceleration_variance,
    weights: Weights = Weights(),
    priors: tuple[float, float] = (1.0, 1.0),
) -> np.ndarray:
    """The same solve with dense matrices: the reference the banded solve is tested against."""
    j, mk, vk, ma, va = _checked(
        source, kinematic_mean, kinematic_variance, acceleration_mean, acceleration_variance
    )
    rk, ra = _regularizer_precisions(vk, va, priors)
    L = second_difference(len(j))
    w = weights
    Dk = np.diag(w.kinematic / vk + w.kinematic_regularizer * rk)
    Da = np.diag(w.acceleration / va + w.acceleration_regularizer * ra)
    rhs = (w.kinematic / vk)[:, None] * mk + (w.kinematic_regularizer * rk)[:, None] * j
    rhs += L.T @ (
        (w.acceleration / va)[:, None] * ma + (w.acceleration_regularizer * ra)[:, None] * (L @ j)
    )
    return np.linalg.solve(Dk + L.T @ Da @ L, rhs)


def _regularizer_precisions(vk, va, priors) -> tuple[np.ndarray, np.ndarray]:
    """§4.3's ``Σ_r⁻¹ = Σ_l``, each variance divided by its predictor's prior variance
    squared (module docstring), the prior raised to ``MIN_VARIANCE`` like the variances:
    an acceleration GP fitted to a constant offset (no acceleration to learn) has a prior
    near 1e-18, and its regulariser precision 1e-6 / 1e-36 swamped every other term
    (the biped's bowed legs: held-out edit error 2.4 std² where the kinematic term alone
    gave 4e-25)."""
    pk, pa = (float(p) for p in priors)
    if not (np.isfinite([pk, pa]).all() and pk > 0 and pa > 0):
        raise CombineError(f"prior variances must be finite and > 0, got {priors}")
    pk, pa = max(pk, MIN_VARIANCE), max(pa, MIN_VARIANCE)
    return vk / pk**2, va / pa**2


def _upper_bands(diagonal_k: np.ndarray, diagonal_a: np.ndarray) -> np.ndarray:
    """``D_k + Lᵀ D_a L`` in LAPACK's upper banded storage (3 rows: +2, +1, main)."""
    n = len(diagonal_k)
    main = diagonal_k.copy()
    first = np.zeros(n)
    second = np.zeros(n)
    taps = (1.0, -2.0, 1.0)
    for i, d in enumerate(diagonal_a):  # row i of L touches frames i, i+1, i+2
        for a in range(3):
            main[i + a] += d * taps[a] ** 2
            if a + 1 < 3:
                first[i + a + 1] += d * taps[a] * taps[a + 1]
        second[i + 2] += d * taps[0] * taps[2]
    return np.vstack([second, first, main])


def _apply_lt(values: np.ndarray, n_frames: int) -> np.ndarray:
    """``Lᵀ`` applied to ``(F−2, D)`` values."""
    out = np.zeros((n_frames, values.shape[1]))
    out[:-2] += values
    out[1:-1] -= 2.0 * values
    out[2:] += values
    return out


def _checked(j, mk, vk, ma, va):
    arrays = [np.asarray(a, dtype=np.float64) for a in (j, mk, vk, ma, va)]
    j, mk, vk, ma, va = arrays
    if j.ndim != 2 or len(j) < 3:
        raise CombineError(f"source must be (F >= 3, D), got {j.shape}")
    n, d = j.shape
    expected = {
        "kinematic_mean": (mk, (n, d)),
        "kinematic_variance": (vk, (n,)),
        "acceleration_mean": (ma, (n - 2, d)),
        "acceleration_variance": (va, (n - 2,)),
    }
    for name, (array, shape) in expected.items():
        if array.shape != shape:
            raise CombineError(f"{name} has shape {array.shape}, expected {shape}")
    for name, array in zip(("source", *expected), arrays, strict=True):
        if not np.isfinite(array).all():
            raise CombineError(f"{name} has non-finite values")
    if vk.min() <= 0 or va.min() <= 0:
        raise CombineError("variances must be > 0 (a GP's predictive variance includes noise)")
    return j, mk, np.maximum(vk, MIN_VARIANCE), ma, np.maximum(va, MIN_VARIANCE)
