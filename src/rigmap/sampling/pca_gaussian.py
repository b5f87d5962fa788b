"""``pca_gaussian``: the paper's sampler, PCA + unit Gaussian around corpus frames (Algorithm 2).

Algorithm 2 repeats ``y' = M⁻¹(M choice(Y) + g)`` with ``g ~ N(0, I)``: pick a
random animator frame, move it by a unit-Gaussian offset in PCA space, map back.
It keeps the correlations between controls (like the multivariate Gaussian)
while sampling densely around every frame the animators made; in the paper it
trains the best network (§6.2, Table 2).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rigmap.sampling.base import (
    RELATIVE_RANK_TOLERANCE,
    Sampler,
    SamplerInputError,
    sign_convention,
)


@dataclass(eq=False, repr=False)
class PCAGaussianSampler(Sampler):
    """Random corpus frame + Gaussian offset along the corpus's principal axes.

    **The offset is in whitened units by default** (``whiten=True``): the PCA
    map ``M`` divides each principal coordinate by that component's standard
    deviation ``√λ_k``, so the paper's unit Gaussian ``g`` becomes, in control
    space, ::

        y' = y_i + scale · Σ_k g_k √λ_k v_k,     g_k ~ N(0, 1)

    an offset whose covariance is ``scale²`` times the corpus covariance.

    Why whitened: with raw PCA coordinates ``M`` is only a rotation, and a
    unit Gaussian is rotation invariant, so the PCA would change nothing — every
    control would get a 1 cm or 1 rad offset whatever its range in the corpus.
    That contradicts the paper's reasons for the PCA: "sample more frequently
    on axes of the data with the largest variance" (§5.2) and "as with the
    Multivariate Gaussian approach, this captures the covariance between rig
    controls" (§6.2). ``whiten=False`` keeps the literal raw-coordinate variant
    for comparison: offsets of standard deviation ``scale`` (in the controls'
    own units, cm or rad) along every axis the corpus moves in.

    Hyper-parameters:

    - ``scale``: standard deviation of ``g`` (1.0 = the paper's unit Gaussian);
      the samples then have covariance about ``(1 + scale²)`` × the corpus's.
    - ``whiten``: see above.
    - ``n_components``: principal axes kept — ``None`` all the corpus moves
      along, an ``int`` that many, a ``float`` in (0, 1) the fewest explaining
      that fraction of the variance. Offsets stay in the kept subspace; the
      chosen frame is kept whole (not projected), so frames are only ever moved
      along the corpus's main axes of variation.

    Axes the corpus never moves along (constant controls, controls always keyed
    together) are dropped, so such controls keep their corpus values.
    """

    name = "pca_gaussian"
    title = "PCA & Unit Gaussian"  # the report's label (Table 2)
    paper_row = 5
    min_corpus_frames = 2

    scale: float = 1.0
    whiten: bool = True
    n_components: Any = None

    def _fit(self, corpus: np.ndarray) -> None:
        who = type(self).__name__
        scale = self.scale
        numeric = isinstance(scale, int | float | np.number) and not isinstance(scale, bool)
        if not numeric or not np.isfinite(scale) or scale < 0:
            raise SamplerInputError(f"{who}: scale must be a finite number >= 0, got {scale!r}")
        if not isinstance(self.whiten, bool | np.bool_):
            raise SamplerInputError(f"{who}: whiten must be true or false, got {self.whiten!r}")

        self.mean_ = corpus.mean(axis=0)
        _, singular_values, axes = np.linalg.svd(corpus - self.mean_, full_matrices=False)
        variances = singular_values**2 / (corpus.shape[0] - 1)
        moving = int((variances > RELATIVE_RANK_TOLERANCE * variances.max()).sum())
        kept = min(moving, self._requested_components(variances[:moving], who))

        self.components_ = sign_convention(axes[:kept])
        self.explained_variance_ = variances[:kept]
        unit = np.sqrt(self.explained_variance_) if self.whiten else np.ones(kept)
        self.offset_std_ = float(self.scale) * unit
        self.corpus_ = corpus.copy()

    def _requested_components(self, variances: np.ndarray, who: str) -> int:
        wanted = self.n_components
        if wanted is None:
            return variances.size
        if isinstance(wanted, bool):
            raise SamplerInputError(f"{who}: n_components must be None, an int or a float")
        if isinstance(wanted, int | np.integer):
            if wanted < 1:
                raise SamplerInputError(f"{who}: n_components must be >= 1, got {wanted}")
            return int(wanted)
        if isinstance(wanted, float) and 0 < wanted < 1:
            if variances.size == 0:
                return 0
            explained = np.cumsum(variances) / variances.sum()
            return int(np.searchsorted(explained, wanted) + 1)
        raise SamplerInputError(
            f"{who}: n_components must be None, an int >= 1 or a fraction of variance "
            f"in (0, 1), got {wanted!r}"
        )

    def _sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        frames = rng.integers(0, self.corpus_.shape[0], size=n)
        g = rng.standard_normal((n, self.offset_std_.size))
        g *= self.offset_std_  # in place: 100 000 draws of 200+ controls are large
        samples = g @ self.components_
        del g
        samples += self.corpus_[frames]
        return samples
