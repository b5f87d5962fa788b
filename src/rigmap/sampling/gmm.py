"""``gmm``: a Gaussian mixture fitted to the corpus (Table 2; 25 components in the paper).

More natural poses than a single Gaussian but, per the paper (§6.2), it
overfits the animator data and the network generalises worse from it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from rigmap.sampling.base import Sampler, SamplerInputError

COVARIANCE_TYPES = ("full", "tied", "diag", "spherical")


@dataclass(eq=False, repr=False)
class GaussianMixtureSampler(Sampler):
    """scikit-learn ``GaussianMixture`` fitted on standardised controls.

    Controls mix centimetres and radians, so the mixture is fitted on each
    control divided by its corpus standard deviation; ``reg_covar`` is then a
    fraction of every control's variance (``1e-3`` = 0.1 %) added to the
    diagonal, which keeps components that own fewer frames than there are
    controls positive definite. Constant controls stay constant.

    Sampling uses the ``rng`` given to ``sample`` (not the mixture's own
    ``random_state``, which only seeds EM initialisation), so one seed decides
    the samples like for every other strategy.
    """

    name = "gmm"
    title = "Gaussian Mixture Model"  # the report's label (Table 2)
    paper_row = 4

    n_components: int = 25
    covariance_type: str = "full"
    reg_covar: float = 1e-3
    max_iter: int = 100
    n_init: int = 1
    random_state: int = 0

    def _fit(self, corpus: np.ndarray) -> None:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.mixture import GaussianMixture

        who = type(self).__name__
        components = self.n_components
        if isinstance(components, bool) or not isinstance(components, int | np.integer):
            raise SamplerInputError(
                f"{who}: n_components must be an integer >= 1, got {components!r}"
            )
        if components < 1:
            raise SamplerInputError(f"{who}: n_components must be >= 1, got {components}")
        if corpus.shape[0] < components:
            raise SamplerInputError(
                f"{who}: {components} mixture components need at least "
                f"{components} corpus frames, got {corpus.shape[0]}"
            )
        if self.covariance_type not in COVARIANCE_TYPES:
            raise SamplerInputError(
                f"{who}: covariance_type must be one of {COVARIANCE_TYPES}, "
                f"got {self.covariance_type!r}"
            )
        if not self.reg_covar > 0:
            raise SamplerInputError(f"{who}: reg_covar must be > 0, got {self.reg_covar}")

        self.center_ = corpus.mean(axis=0)
        # Mapping back multiplies by the true spread, so the regularisation noise
        # added to a constant control's (zero) column is cancelled there.
        self.scale_ = corpus.std(axis=0)
        standardised = (corpus - self.center_) / np.where(self.scale_ > 0, self.scale_, 1.0)
        mixture = GaussianMixture(
            n_components=int(components),
            covariance_type=self.covariance_type,
            reg_covar=self.reg_covar,
            max_iter=self.max_iter,
            n_init=self.n_init,
            random_state=self.random_state,
        )
        with warnings.catch_warnings():
            # Replaced below by a warning that says which sampler and what it means.
            warnings.simplefilter("ignore", ConvergenceWarning)
            mixture.fit(standardised)
        if not mixture.converged_:
            warnings.warn(
                f"{who}: EM did not converge in max_iter={self.max_iter} iterations "
                f"(lower bound {mixture.lower_bound_:.4g}); samples come from the last iterate",
                stacklevel=3,
            )
        self.mixture_ = mixture
        self.weights_ = mixture.weights_ / mixture.weights_.sum()
        self._component_factors = _square_root_factors(mixture, corpus.shape[1])

    @property
    def n_components_(self) -> int:
        """Number of mixture components actually fitted."""
        return len(self.mixture_.weights_)

    @property
    def means_(self) -> np.ndarray:
        """Component means in control units, ``(K, C_used)``."""
        return self.mixture_.means_ * self.scale_ + self.center_

    def _sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        n_controls = self.center_.size
        labels = rng.choice(self.n_components_, size=n, p=self.weights_)
        normal = rng.standard_normal((n, n_controls))
        standardised = np.empty((n, n_controls))
        for k in range(self.n_components_):
            rows = np.flatnonzero(labels == k)
            if rows.size:
                offset = _apply_factor(self._component_factors[k], normal[rows])
                standardised[rows] = self.mixture_.means_[k] + offset
        standardised *= self.scale_  # in place: the draw can be hundreds of MB
        standardised += self.center_
        return standardised


def _square_root_factors(mixture, n_controls: int) -> list[np.ndarray]:
    """Per component, ``L`` with ``L Lᵀ = Σ_k``: a matrix (full, tied) or a vector (diagonal)."""
    covariances = mixture.covariances_
    n_components = len(mixture.weights_)
    kind = mixture.covariance_type
    if kind == "full":
        return [np.linalg.cholesky(covariances[k]) for k in range(n_components)]
    if kind == "tied":
        shared = np.linalg.cholesky(covariances)
        return [shared] * n_components
    if kind == "diag":
        return [np.sqrt(covariances[k]) for k in range(n_components)]
    return [np.full(n_controls, np.sqrt(covariances[k])) for k in range(n_components)]


def _apply_factor(factor: np.ndarray, normal: np.ndarray) -> np.ndarray:
    return normal @ factor.T if factor.ndim == 2 else normal * factor
