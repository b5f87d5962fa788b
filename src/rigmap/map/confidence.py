"""How far each mapped frame lies from what the mapping learned: a per-frame confidence.

A regression is trustworthy near its training poses and guesses far from them (§7: the
mapping extrapolates poorly outside the corpus). The confidence of a frame is
``exp(-½ (d / s)²)``, with ``d`` the distance of the frame's input row (the subset's
joints around the virtual COG, standardised as the regressor sees them) to the nearest
GPR support pose and ``s`` the median distance between support poses and their nearest
neighbour: 1 on a support pose, 0.61 one typical spacing away, 0.01 three away. The
form and the scale are ours (the paper has no confidence); regressors without support
poses (the network) give NaN.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from rigmap.map.partial import SubsetMapping


def frame_confidence(mapping: SubsetMapping, world: np.ndarray) -> np.ndarray:
    """Per frame of ``world`` ``(F, K, 3)`` (the subset's joints), a confidence in [0, 1]."""
    regressor = mapping.mapping.regressor
    if not hasattr(regressor, "support_inputs_"):
        return np.full(len(world), np.nan)
    rows = mapping.subset.pose_rows(world)
    inputs = mapping.mapping.placement.inputs(rows, "map confidence")
    standardised = (inputs - regressor.x_mean_) / regressor.x_std_
    support = np.asarray(regressor.support_inputs_)
    tree = cKDTree(support)
    if len(support) < 2:
        return np.ones(len(world))
    spacing = float(np.median(tree.query(support, k=2)[0][:, 1]))
    distance = tree.query(standardised, k=1)[0]
    return np.exp(-0.5 * (distance / max(spacing, 1e-12)) ** 2)
