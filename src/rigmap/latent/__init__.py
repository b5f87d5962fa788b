"""Latent synthesis (Bailey et al. 2016): scaling, PCA and a GPLVM per labelled set; a
particle driven by commands in those spaces, with transitions between them."""

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
# the synthesis side: rigmap.latent.library (labelled sets, one model per label),
# .particle (§5.1), .transitions (§5.2), .synthesis (commands, controller, §5.3),
# .scripts (YAML command scripts), .motion_graph (the Kovar et al. 2002 baseline)
