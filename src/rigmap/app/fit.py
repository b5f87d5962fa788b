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
from rigmap.store.layout import REPLICATED_REGRESSORS


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
        layout, model = _replicate_of(config)
        return fit_model(rig, model, sampler, layout, config, started=started, **options)


def _replicate_of(config: Mapping[str, Any]) -> tuple[Layout, Regressor]:
    """The layout and regressor of a fit; a ``replicate`` seed k (issue #36) re-fits a trained
    network with only its training seed set to k, into the replicate's own folder."""
    replicate = config.get("replicate")
    try:
        layout = Layout.from_paths(config["paths"], replicate)
    except ValueError as error:
        raise FitInputError(str(error)) from None
    model = instantiate_as(config["regressor"], Regressor, "regressor", FitInputError)
    if replicate is None:
        return layout, model
    if model.name not in REPLICATED_REGRESSORS:
        raise FitInputError(
            f"replicate={replicate}: only the trained networks "
            f"({', '.join(REPLICATED_REGRESSORS)}) have replicate seeds, not {model.name}"
        )
    seeded = {**config["regressor"], "seed": replicate}
    return layout, instantiate_as(seeded, Regressor, "regressor", FitInputError)


def fit_command(overrides: list[str], config_dir=None) -> FitResult:
    """``rigmap fit``: ``conf/`` composed with ``overrides``, the rig's ``_overrides_``
    applied, then the fit the stage runs."""
    from rigmap.app.config import compose_config
    from rigmap.app.stage import apply_rig_overrides

    return fit_from_config(apply_rig_overrides(compose_config(overrides, config_dir)))
