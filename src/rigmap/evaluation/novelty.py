"""Per-frame confidence: how far a test frame lies from the frames the mapping learned from.

A regressor is only as good as its training corpus is near the pose it is asked about
(issue #15: per-frame GPR error follows the distance to the nearest training frame), so
a user mapping new motion wants to know which frames to check. *Novelty* is that
distance, measured where the regressor looks: the COG-relative joint positions of its
own inputs (the placement's heading frame), as the mean RMS joint distance to the
``NEIGHBOURS`` nearest frames it learned from, in the rig's length unit: the training
corpus (and the rest pose) for the GPR, the network and the mean predictor, and also its
own posed draws for the joint-space network, which learns far beyond the corpus
(measured to the corpus alone, its biped rank correlation was 0.18; to everything it
learned from, 0.59). Higher
novelty means lower confidence. It needs no extra model; the evaluation reports its
Spearman correlation with the per-frame joint error beside the error itself.

Why centimetres and not standardised inputs: columns that barely move in the corpus
(a joint the animators never shifted) get a tiny std, and dividing by it lets numerical
noise decide the distance; on the biped test clips that halved the rank correlation
with the GPR's error (0.49 against 0.69 measured; the choice is ours).
scikit-learn's ``NearestNeighbors`` does the search.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import spearmanr
from sklearn.neighbors import NearestNeighbors

from rigmap.error_measures import MetricInputError, finite_array

#: what ``novelty`` measures, written beside the numbers
NOVELTY_MEASURE = (
    "mean RMS joint distance (rig length unit) from the frame's COG-relative joint positions "
    "in the regressor's heading frame to the 5 nearest frames it learned from (the training "
    "corpus; for the joint-space network also its own drawn poses); higher = less confident"
)


#: frames a test frame's novelty averages over (ours): to the joint-space network's 54 000
#: draws the nearest one alone is luck — over four draw sets of one config the biped's rank
#: correlation was 0.52-0.62 at 1 neighbour, 0.57-0.61 at 5; the corpus-only methods move by
#: under 0.01 (``benchmarks/novelty_neighbours.py``)
NEIGHBOURS = 5


@dataclass(frozen=True)
class Novelty:
    """Mean RMS joint distance to the nearest learned frames, in a mapping's input space."""

    n_joints: int
    neighbours: NearestNeighbors

    @classmethod
    def from_training(
        cls, training_inputs: Any, n_joints: int, neighbours: int = NEIGHBOURS
    ) -> Novelty:
        """From the regressor inputs ``(N, D)`` of the frames it learned from, whose first
        ``3 * n_joints`` columns are the COG-relative joint positions; ``neighbours``
        nearest frames are averaged (all of them when there are fewer)."""
        inputs = cls._joints(training_inputs, n_joints, "training inputs")
        if len(inputs) == 0:
            raise MetricInputError("novelty: expected at least one training frame, got none")
        if int(neighbours) != neighbours or neighbours < 1:
            raise MetricInputError(f"novelty: neighbours must be an integer >= 1, got {neighbours}")
        search = NearestNeighbors(n_neighbors=min(int(neighbours), len(inputs)))
        return cls(n_joints, search.fit(inputs))

    def distances(self, inputs: Any) -> np.ndarray:
        """``(N,)`` mean RMS joint distance of each row of ``inputs`` to its nearest
        learned frames."""
        joints = self._joints(inputs, self.n_joints, "inputs")
        distance, _ = self.neighbours.kneighbors(joints)
        return distance.mean(axis=1) / np.sqrt(self.n_joints)

    @staticmethod
    def _joints(inputs: Any, n_joints: int, what: str) -> np.ndarray:
        inputs = finite_array(inputs, f"novelty: {what}")
        if inputs.ndim != 2 or inputs.shape[1] < 3 * n_joints or n_joints < 1:
            raise MetricInputError(
                f"novelty: expected {what} of shape (N, >= {3 * n_joints}) for {n_joints} "
                f"joints, got {inputs.shape}"
            )
        return inputs[:, : 3 * n_joints]


def rank_correlation(novelty: np.ndarray, errors: np.ndarray) -> float | None:
    """Spearman's ρ between novelty and error; ``None`` when either is constant."""
    novelty, errors = np.asarray(novelty, float), np.asarray(errors, float)
    if novelty.shape != errors.shape or novelty.ndim != 1:
        raise MetricInputError(
            f"rank_correlation: expected two vectors of one length, got {novelty.shape} "
            f"and {errors.shape}"
        )
    if len(novelty) < 3 or np.ptp(novelty) == 0 or np.ptp(errors) == 0:
        return None
    return float(spearmanr(novelty, errors).statistic)
