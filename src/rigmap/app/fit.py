"""The fit job (``pipelines/fit.py``, ``rigmap fit``): the composed config becomes a rig, an
unfitted regressor, the sampler's name and a :class:`~rigmap.store.Layout`, and
:func:`rigmap.regression.fitting.fit_model` does the work."""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

from rigmap.app.objects import instantiate_as, plain, sampler_name
from rigmap.regression.base import Regressor
from rigmap.regression.fitting import FitInputError, FitResult, Log, fit_model
from rigmap.rigs import load
from rigmap.store import Layout


def fit_from_config(config: Mapping[str, Any], *, log: Log | None = None) -> FitResult:
    """Read the training data a composed config (``rig``, ``regressor``, ``sampler``,
    ``paths`` …; a ``DictConfig`` is resolved first) names, fit its regressor, write the
    model folder."""
    config = plain(config)
    options = {} if log is None else {"log": log}
    started = time.perf_counter()
    rig_options = {k: v for k, v in dict(config["rig"]).items() if k != "corpus"}
    with load(rig_options) as rig:  # a DCC rig's worker processes end with the fit
        sampler = sampler_name(config["sampler"])
        model = instantiate_as(config["regressor"], Regressor, "regressor", FitInputError)
        layout = Layout.from_paths(config["paths"])
        return fit_model(rig, model, sampler, layout, config, started=started, **options)


def fit_command(overrides: list[str], config_dir=None) -> FitResult:
    """``rigmap fit``: ``conf/`` composed with ``overrides``, the rig's ``_overrides_``
    applied, then the fit the stage runs."""
    from rigmap.app.config import compose_config
    from rigmap.app.stage import apply_rig_overrides

    return fit_from_config(apply_rig_overrides(compose_config(overrides, config_dir)))
