"""Latent synthesis (Bailey, Watt & O'Brien 2016): scaling, PCA and a GPLVM per labelled set."""

from rigmap.latent.control_scaling import ControlScaling, fit_control_scaling
from rigmap.latent.errors import LatentInputError
from rigmap.latent.gplvm import GPLVM, GPLVMSettings
from rigmap.latent.model import LatentModel, segment_times
from rigmap.latent.pca import VARIANCE_FRACTION, fit_pca

__all__ = [
    "GPLVM",
    "VARIANCE_FRACTION",
    "ControlScaling",
    "GPLVMSettings",
    "LatentInputError",
    "LatentModel",
    "fit_control_scaling",
    "fit_pca",
    "segment_times",
]
