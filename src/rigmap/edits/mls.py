"""Moving least squares (§4.4), the alternative estimator behind the GP's interface.

"The moving least-squares formulation is ``W_p A x = W_p B``, where ``W_p`` is a diagonal
weight matrix that depends on the source point we want to evaluate ``p``, ``A`` is the
source training data, and ``B`` is the target training data … We computed W using a
Gaussian function where the mean of the Gaussian was p. We tried various variance values
by hand. We used the mean of the three highest weights as the confidence value.
(Confidence can be considered a measure of inverse variance.)" (§4.4)

:class:`MovingLeastSquares` has :class:`rigmap.edits.gp.SharedGP`'s ``fit(X, Y)`` /
``predict(X) → Prediction(mean, variance)`` / ``state()`` / ``from_state``, so
:class:`rigmap.edits.propagation.EditModel` takes either (``estimator="mls"``). Per query
``p`` it solves the weighted least-squares problem ``min_x Σ_i w_i(p) |[1, a_i] x − b_i|²``
with ``w_i = exp(−|p − a_i|² / (2 h²))`` and returns ``[1, p] x``. Choices that are ours
(the paper gives none):

- the map is affine (a constant column beside ``A``: ``W_p A x = W_p B`` without it forces
  the map through the origin of the standardised features), with a ridge
  ``1e-6 · Σ w_i`` on the slope;
- ``A`` is the training inputs standardised per column and projected on their first
  ``components`` principal directions (16: with the 189 features of a skeleton the local
  system would be 190 × 190 per frame, and rank-deficient with few weighted neighbours);
- ``h`` is chosen, instead of by hand, from a grid of fractions of the median pairwise
  distance by 5-fold cross-validation over contiguous blocks of training frames
  (neighbouring frames are near-duplicates, so leave-one-out would pick the smallest
  ``h``), scoring the held-out likelihood under the variance below (the squared error
  alone picks a small ``h`` whose confidence vanishes off the examples);
- the variance is ``σ² / confidence``, ``confidence`` the mean of the three highest
  weights (the paper's), with ``σ²`` fitted so that the cross-validation residuals are
  calibrated: ``σ² = mean_i(r_i² · confidence_i)``, ``r_i²`` the mean squared residual over
  the outputs of held-out frame ``i`` (the maximum-likelihood value for Gaussian residuals
  of variance ``σ² / confidence``). Far from the examples all weights vanish, the variance
  grows without bound and the combined solve falls back to the source, as with the GP.
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

from rigmap.edits.gp import GPInputError, Prediction, _checked
from rigmap.gp.distances import expanded_squared_distances

COMPONENTS = 16  # ours (module docstring)
BANDWIDTH_FACTORS = (0.03, 0.06, 0.12, 0.25, 0.5, 1.0)  # × median pairwise distance
FOLDS = 5
RIDGE = 1e-6
_CHUNK = 256  # query frames per batched solve
_MAX_LOG = 46.0  # log(1/confidence) capped (ours): at most 1e20 σ², a precision ≈ 0 that
# keeps the banded solve well-conditioned


class MovingLeastSquares:
    """Affine moving least squares with Gaussian weights and a confidence (see the module)."""

    def __init__(self, components: int = COMPONENTS, bandwidth: float | None = None):
        if components < 1:
            raise GPInputError(f"MLS components must be at least 1, got {components}")
        self.components = components
        self.bandwidth = bandwidth  # None: cross-validated

    def fit(self, X, Y, **_) -> MovingLeastSquares:
        X, Y = _checked(X, "X"), _checked(Y, "Y")
        if len(X) != len(Y) or len(X) < 2 * FOLDS:
            raise GPInputError(
                f"expected X and Y with the same N >= {2 * FOLDS} rows, got {X.shape}, {Y.shape}"
            )
        self.x_mean_ = X.mean(axis=0)
        std = X.std(axis=0)
        self.x_std_ = np.where(std > 0, std, 1.0)
        standard = (X - self.x_mean_) / self.x_std_
        k = min(self.components, *standard.shape)
        _, _, vt = np.linalg.svd(standard, full_matrices=False)
        self.basis_ = vt[:k].T
        self.A_ = standard @ self.basis_
        self.B_ = Y.copy()
        if self.bandwidth is None:
            sq = expanded_squared_distances(self.A_, self.A_)
            scale = float(np.sqrt(np.median(sq[np.triu_indices(len(sq), 1)])))
            scale = scale if scale > 0 else 1.0
            scores = {}
            for factor in BANDWIDTH_FACTORS:
                residual, log_confidence = self._cross_validate(factor * scale)
                scores[factor] = (_held_out_nll(residual, log_confidence), residual, log_confidence)
            factor = min(scores, key=lambda f: scores[f][0])
            self.bandwidth_ = factor * scale
            _, residual, log_confidence = scores[factor]
        else:
            self.bandwidth_ = float(self.bandwidth)
            residual, log_confidence = self._cross_validate(self.bandwidth_)
        self.sigma2_ = _sigma2(residual, log_confidence)
        self.cv_error_ = float(residual.mean())
        # the names EditModel's callers read off a fitted GP
        self.length_scale_, self.signal_, self.noise_ = self.bandwidth_, 1.0, self.sigma2_**0.5
        self.iterations_, self.log_marginal_likelihood_ = 0, None
        return self

    def _cross_validate(self, bandwidth: float) -> tuple[np.ndarray, np.ndarray]:
        """Per training frame: the mean squared residual over the outputs when its block is
        held out, and its log-confidence then."""
        n = len(self.A_)
        blocks = np.array_split(np.arange(n), FOLDS)
        residual, log_confidence = np.empty(n), np.empty(n)
        for block in blocks:
            keep = np.setdiff1d(np.arange(n), block)
            mean, conf = _solve(self.A_[block], self.A_[keep], self.B_[keep], bandwidth)
            residual[block] = ((mean - self.B_[block]) ** 2).mean(axis=1)
            log_confidence[block] = conf
        return residual, log_confidence

    @property
    def prior_variance(self) -> float:
        """MLS has no prior: 1, so the combined solve's regulariser precision is its variance
        (§4.3 as written; :func:`rigmap.edits.combine.combine`)."""
        return 1.0

    def predict(self, X) -> Prediction:
        if not hasattr(self, "A_"):
            raise GPInputError("this MovingLeastSquares is not fitted yet: call fit(X, Y) first")
        X = _checked(X, "X")
        if X.shape[1] != len(self.x_mean_):
            raise GPInputError(f"X has {X.shape[1]} columns, MLS was fitted on {len(self.x_mean_)}")
        query = ((X - self.x_mean_) / self.x_std_) @ self.basis_
        mean, log_confidence = _solve(query, self.A_, self.B_, self.bandwidth_)
        return Prediction(mean, self.sigma2_ * np.exp(np.minimum(-log_confidence, _MAX_LOG)))

    # --- saving: plain arrays, no pickle (rigmap.edits.propagation.save_model) -------------
    def state(self) -> dict[str, np.ndarray]:
        return {
            "x_mean_": self.x_mean_,
            "x_std_": self.x_std_,
            "basis_": self.basis_,
            "A_": self.A_,
            "B_": self.B_,
            "hyper": np.array([self.bandwidth_, self.sigma2_, self.cv_error_, self.components]),
        }

    @classmethod
    def from_state(cls, arrays) -> MovingLeastSquares:
        hyper = np.asarray(arrays["hyper"], dtype=np.float64)
        mls = cls(components=int(hyper[3]), bandwidth=float(hyper[0]))
        for name in ("x_mean_", "x_std_", "basis_", "A_", "B_"):
            setattr(mls, name, np.asarray(arrays[name], dtype=np.float64))
        mls.bandwidth_, mls.sigma2_, mls.cv_error_ = (float(v) for v in hyper[:3])
        mls.length_scale_, mls.signal_, mls.noise_ = mls.bandwidth_, 1.0, mls.sigma2_**0.5
        mls.iterations_, mls.log_marginal_likelihood_ = 0, None
        return mls


def _sigma2(residual: np.ndarray, log_confidence: np.ndarray) -> float:
    """σ² making held-out residuals of variance σ² / confidence most likely."""
    return max(float(np.mean(residual * np.exp(log_confidence))), 1e-300)


def _held_out_nll(residual: np.ndarray, log_confidence: np.ndarray) -> float:
    """Mean Gaussian negative log-likelihood (per output, constants dropped) of held-out
    residuals under variance σ² / confidence, σ² at its best: how a bandwidth is chosen."""
    sigma2 = _sigma2(residual, log_confidence)
    return float(
        np.mean(np.log(sigma2) - log_confidence + residual * np.exp(log_confidence) / sigma2)
    )


def _solve(query: np.ndarray, A: np.ndarray, B: np.ndarray, bandwidth: float):
    """Means ``(Q, D)`` and log-confidences ``(Q,)`` of the weighted affine fits at
    ``query`` (logarithms: far from the examples the confidence underflows)."""
    n, k = A.shape
    Z = np.hstack([np.ones((n, 1)), A])
    means, confidences = [], []
    for start in range(0, len(query), _CHUNK):
        q = query[start : start + _CHUNK]
        sq = expanded_squared_distances(q, A)
        nearest = -0.5 * np.partition(sq, min(2, n - 1), axis=1)[:, :3] / bandwidth**2
        confidences.append(logsumexp(nearest, axis=1) - np.log(nearest.shape[1]))  # log
        # the local fit is unchanged by scaling a query's weights: relative to its nearest
        # example, so that far queries (every weight underflowing) stay solvable
        weights = np.exp(-0.5 * (sq - sq.min(axis=1, keepdims=True)) / bandwidth**2)
        # per query: M = Zᵀ W Z + ridge, rhs = Zᵀ W B — as two batched products
        weighted = weights[:, None, :] * Z.T[None]  # (Q, k + 1, N), contiguous
        M = weighted @ Z
        ridge = RIDGE * weights.sum(axis=1)
        M[:, np.arange(1, k + 1), np.arange(1, k + 1)] += ridge[:, None]
        rhs = (weighted.reshape(-1, n) @ B).reshape(len(q), k + 1, -1)
        try:
            x = np.linalg.solve(M, rhs)
        except np.linalg.LinAlgError:
            x = np.stack(
                [np.linalg.lstsq(m, r, rcond=None)[0] for m, r in zip(M, rhs, strict=True)]
            )
        zq = np.hstack([np.ones((len(q), 1)), q])
        means.append(np.einsum("qi,qid->qd", zq, x))
    return np.vstack(means), np.concatenate(confidences)
