"""``multivariate_gaussian``: one Gaussian with the corpus's full covariance (Table 2)."""

from __future__ import annotations

import numpy as np

from rigmap.sampling.base import (
    RELATIVE_RANK_TOLERANCE,
    CorpusGaussianSampler,
    sign_convention,
)


class MultivariateGaussianSampler(CorpusGaussianSampler):
    """``N(mean, Σ)`` with ``Σ`` the corpus covariance (``ddof=1``).

    Animator corpora rarely span every control direction (constant controls,
    controls keyed together), so ``Σ`` is often singular. Sampling uses the
    eigen-decomposition ``Σ = V diag(w) Vᵀ`` with round-off eigenvalues set to
    zero rather than a Cholesky factor, which would fail there; the samples
    then stay exactly in the span the corpus moves in.
    """

    name = "multivariate_gaussian"
    title = "Multivariate Gaussian"  # the report's label (Table 2)
    paper_row = 3

    def _fit_spread(self, corpus: np.ndarray) -> None:
        self.covariance_ = np.atleast_2d(np.cov(corpus, rowvar=False, ddof=1))
        variances, vectors = np.linalg.eigh(self.covariance_)
        vectors = sign_convention(vectors.T).T
        # Rows of the factor map a unit normal draw to an offset with covariance Σ.
        variances[variances <= RELATIVE_RANK_TOLERANCE * variances.max()] = 0.0
        self.factor_ = vectors * np.sqrt(variances)

    def _spread(self, draws: np.ndarray) -> np.ndarray:
        return draws @ self.factor_.T
