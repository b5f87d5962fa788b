"""The errors the regressors raise on purpose: bad inputs, another rig's model, a bad file."""

from __future__ import annotations

from rigmap.errors import RigmapError
from rigmap.rigs.base import RigInputError


class RegressionInputError(RigInputError):
    """Inputs given to a regressor have the wrong shape or bad values."""


class ModelMismatchError(RigmapError, ValueError):
    """A saved model does not belong to the rig or data it is used with."""


class ModelFileError(RigmapError, ValueError):
    """A model folder is incomplete, corrupt or of another kind of model."""
