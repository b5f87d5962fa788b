"""The GP log marginal likelihood of outputs sharing one kernel (numpy or torch)."""

from __future__ import annotations

import math

from rigmap.gp.solve import log_det

LOG_2PI = math.log(2 * math.pi)


def negative_log_marginal_likelihood(Y, alpha, L):
    """``½ Σ Y ∘ K⁻¹Y + (D/2) ln|K| + (ND/2) ln 2π`` for ``D`` outputs ``Y`` ``(N, D)``
    drawn from one GP: ``alpha = K⁻¹ Y`` and ``L`` the lower Cholesky factor of ``K``
    (:mod:`rigmap.gp.solve`). A tensor keeps the autograd graph."""
    n, d = Y.shape
    return 0.5 * (Y * alpha).sum() + 0.5 * d * log_det(L) + 0.5 * n * d * LOG_2PI
