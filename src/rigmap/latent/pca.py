"""Linear reduction of scaled controls to a variance fraction (Bailey et al. 2016, §4.2).

scikit-learn's PCA with a fractional ``n_components`` keeps the fewest components whose
explained variance reaches the fraction, which is the paper's ``v(d_pca) ≈ 0.85``
rule; its ``transform`` is ``T_pcaᵀ z̃`` without whitening, as in the paper.
"""

from __future__ import annotations

import numpy as np
from sklearn.decomposition import PCA

from rigmap.latent.errors import LatentInputError

VARIANCE_FRACTION = 0.85  # the paper's


def fit_pca(Z, *, variance: float = VARIANCE_FRACTION, n_components: int | None = None) -> PCA:
    """A fitted PCA of ``Z`` ``(N, D)``: to ``variance`` of the total, or a fixed size."""
    Z = np.asarray(Z, dtype=np.float64)
    if Z.ndim != 2 or len(Z) < 2:
        raise LatentInputError(f"PCA needs an (N ≥ 2, D) array, got shape {Z.shape}")
    if not np.isfinite(Z).all():
        raise LatentInputError("PCA input has non-finite values")
    if n_components is None:
        if not 0.0 < variance < 1.0:
            raise LatentInputError(f"PCA variance fraction must be in (0, 1), got {variance}")
        pca = PCA(n_components=variance, svd_solver="full")
    else:
        if not 1 <= n_components <= min(Z.shape):
            raise LatentInputError(
                f"PCA n_components must be in [1, {min(Z.shape)}], got {n_components}"
            )
        pca = PCA(n_components=n_components, svd_solver="full")
    return pca.fit(Z)
