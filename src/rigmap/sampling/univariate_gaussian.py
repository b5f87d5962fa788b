"""``univariate_gaussian``: each used control from its own normal distribution (Table 2).

Per-control mean and standard deviation of the corpus, no correlation between
controls, so poses look unnatural (paper §6.2, Fig. 4 second row).
"""

from __future__ import annotations

import numpy as np

from rigmap.sampling.base import CorpusGaussianSampler


class UnivariateGaussianSampler(CorpusGaussianSampler):
    """Independent ``N(mean_c, std_c²)`` per control; ``std`` uses ``ddof=1``.

    ``ddof=1`` makes ``std_**2`` the diagonal of the multivariate strategy's
    covariance, so the two differ only in the off-diagonal terms.
    """

    name = "univariate_gaussian"
    title = "Univariate Gaussian"  # the report's label (Table 2)
    paper_row = 2

    def _fit_spread(self, corpus: np.ndarray) -> None:
        self.std_ = corpus.std(axis=0, ddof=1)

    def _spread(self, draws: np.ndarray) -> np.ndarray:
        draws *= self.std_
        return draws
