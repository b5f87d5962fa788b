"""Left and right: the two sides of a symmetric character and the mirror between them.

The built-in characters face +Z with +X on their left, so mirroring is a sign on X.
"""

from __future__ import annotations

import numpy as np

#: (suffix, sign of X) for the character's left and right
SIDES = (("l", 1.0), ("r", -1.0))


def mirror(point, sign: float) -> np.ndarray:
    """``point`` (cm) on the side whose X sign is ``sign`` (a left-side point when ``sign`` = 1)."""
    p = np.asarray(point, dtype=np.float64).copy()
    p[0] *= sign
    return p
