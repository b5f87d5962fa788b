"""Random but plausible control vectors for tests."""

from __future__ import annotations

import numpy as np


def random_used_controls(rig, n: int, seed: int, spread: float = 0.3) -> np.ndarray:
    """Full control vectors with the used controls moved a fraction into their soft range."""
    rng = np.random.default_rng(seed)
    used = rig.controls.used_indices
    Y = rig.default_controls(n)
    lo, hi = rig.controls.lower[used], rig.controls.upper[used]
    target = rng.uniform(lo, hi, size=(n, len(used)))
    Y[:, used] = (1 - spread) * Y[:, used] + spread * target
    return Y
