"""``uniform``: every used control drawn independently and uniformly (Table 2).

Ignores how controls move together, which is why its poses look extreme
(paper §6.2, Fig. 4 top row), yet it covers the rig space widely.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rigmap.sampling.base import (
    Sampler,
    SamplerInputError,
    check_bounds,
    check_lower_upper,
)

RANGES = ("corpus", "soft")


@dataclass(eq=False, repr=False)
class UniformSampler(Sampler):
    """Uniform per control within the corpus range or a given soft range.

    ``range="corpus"``: each control between its minimum and maximum in the
    corpus. ``range="soft"``: between ``lower`` and ``upper``, one value per
    used control (typically the rig's soft range,
    ``rig.controls.lower[rig.controls.used_indices]``; centimetres for
    translations, radians for rotations).
    """

    name = "uniform"
    title = "Uniform"  # the report's label (Table 2)
    paper_row = 1

    range: str = "corpus"
    lower: Any = None
    upper: Any = None

    def _fit(self, corpus: np.ndarray) -> None:
        who = type(self).__name__
        if self.range == "corpus":
            if self.lower is not None or self.upper is not None:
                raise SamplerInputError(
                    f"{who}: lower/upper are only used with range='soft', but range='corpus'"
                )
            self.lower_ = corpus.min(axis=0)
            self.upper_ = corpus.max(axis=0)
        elif self.range == "soft":
            if self.lower is None or self.upper is None:
                raise SamplerInputError(
                    f"{who}: range='soft' needs lower and upper (one value per used control, "
                    "e.g. rig.controls.lower[rig.controls.used_indices]); got "
                    f"lower={'None' if self.lower is None else 'given'}, "
                    f"upper={'None' if self.upper is None else 'given'}"
                )
            n_controls = corpus.shape[1]
            lower = check_bounds(self.lower, n_controls, "lower", who)
            upper = check_bounds(self.upper, n_controls, "upper", who)
            if not (np.isfinite(lower).all() and np.isfinite(upper).all()):
                raise SamplerInputError(f"{who}: a uniform soft range must be finite")
            check_lower_upper(lower, upper, who)
            self.lower_, self.upper_ = lower, upper
        else:
            raise SamplerInputError(f"{who}: range must be one of {RANGES}, got {self.range!r}")

    def _sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(self.lower_, self.upper_, size=(n, self.lower_.size))
