"""The errors of :mod:`rigmap.latent`: bad training sets and bad poses, named by field."""

from __future__ import annotations

from rigmap.errors import RigmapError


class LatentInputError(RigmapError, ValueError):
    """Bad input to a latent model: wrong shape, non-finite values, too-short segments."""
