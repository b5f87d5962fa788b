"""``none``: no extra samples; the network learns from the animator corpus alone."""

from __future__ import annotations

import numpy as np

from rigmap.sampling.base import Sampler


class NoExtraSamples(Sampler):
    """The baseline of Table 2 without supersampling: ``sample`` gives ``(0, C_used)``.

    It still validates and remembers the corpus width, so downstream code can
    concatenate its (empty) output with the corpus like any other strategy's.
    """

    name = "none"
    title = "No Extra Samples"  # the report's label (Table 2)
    paper_row = 0

    def _fit(self, corpus: np.ndarray) -> None:
        pass

    def _sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return np.empty((0, self.n_controls_), dtype=np.float64)
