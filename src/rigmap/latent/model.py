"""One latent model of a labelled set: control scaling → PCA → GPLVM (Bailey et al. 2016, §4).

``LatentModel.fit(rig, P, segments, fps=…)`` on used-control values ``P`` ``(N, C)``;
``to_controls(X)`` maps latent points back (§4.4: GP mean, PCA back-projection, unscale,
then clamp to the controls' soft ranges — ours: the GP mean can overshoot them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.decomposition import PCA

from rigmap.latent.control_scaling import ControlScaling, check_values, fit_control_scaling
from rigmap.latent.errors import LatentInputError
from rigmap.latent.gplvm import GPLVM, GPLVMSettings
from rigmap.latent.pca import VARIANCE_FRACTION, fit_pca


def segment_times(segments, fps: float) -> np.ndarray:
    """Frame times in seconds, counted from each segment's first frame (in order of rows)."""
    segments = np.asarray(segments)
    times = np.zeros(len(segments))
    for label in np.unique(segments):
        rows = np.flatnonzero(segments == label)
        times[rows] = np.arange(len(rows)) / fps
    return times


@dataclass
class LatentModel:
    scaling: ControlScaling
    pca: PCA
    gplvm: GPLVM

    @classmethod
    def fit(
        cls,
        rig,
        P,
        segments,
        *,
        fps: float,
        variance: float = VARIANCE_FRACTION,
        n_pca: int | None = None,
        settings: GPLVMSettings | None = None,
        scale: bool = True,
    ) -> LatentModel:
        """Fit all three stages; ``scale=False`` skips §4.1 (unit weights), for comparison."""
        P = check_values(P, len(rig.controls.used_indices), "controls")
        segments = np.asarray(segments)
        if segments.shape != (len(P),):
            raise LatentInputError(f"segments must be ({len(P)},), got {segments.shape}")
        scaling = fit_control_scaling(rig, P)
        if not scale:
            scaling = ControlScaling(
                scaling.names,
                np.ones_like(scaling.weights),
                scaling.mean,
                scaling.lower,
                scaling.upper,
            )
        pca = fit_pca(scaling.scale(P), variance=variance, n_components=n_pca)
        Y = pca.transform(scaling.scale(P))
        gplvm = GPLVM(settings).fit(Y, segments, segment_times(segments, fps))
        return cls(scaling, pca, gplvm)

    @property
    def latent(self) -> np.ndarray:
        """The training frames' latent points ``(N, q)``."""
        return self.gplvm.X

    def to_pca(self, P) -> np.ndarray:
        return self.pca.transform(self.scaling.scale(P))

    def to_controls(self, X, *, clamp: bool = True) -> np.ndarray:
        """Used-control values ``(M, C)`` at latent points ``(M, q)``."""
        Z = self.pca.inverse_transform(self.gplvm.mean(X))
        return self.scaling.unscale(Z, clamp=clamp)

    def project(self, P, *, max_iter: int = 100) -> np.ndarray:
        """Latent points of poses ``P`` ``(M, C)`` (Eq 15 after Eq 13's scaling and PCA)."""
        return self.gplvm.project(self.to_pca(P), max_iter=max_iter)
