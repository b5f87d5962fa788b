"""Objects built from config nodes: ``hydra.utils.instantiate``, then checked to be the kind
the caller asked for, so a wrong ``_target_`` is one clear error naming the group.

The one module outside :mod:`rigmap.app` that imports Hydra, because ``rigmap.map``'s
``subset_model`` and ``partial_report`` still build their regressor from a config node
(and ``rigmap.app`` imports ``rigmap.map`` through ``rigmap.edits``, so they cannot import
the application layer without a cycle); it joins :mod:`rigmap.app.objects` once they take
a built regressor. The application layer uses it through :mod:`rigmap.app.objects`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def instantiate_as(config: Mapping[str, Any], base: type, group: str, error: type[Exception]):
    """``config`` (with its ``_target_``) built and checked to be a ``base``; ``group`` is the
    config group named in the message (``sampler``, ``regressor`` …)."""
    import hydra.utils
    from omegaconf import DictConfig, OmegaConf

    if isinstance(config, DictConfig):
        config = OmegaConf.to_container(config, resolve=True)
    if not isinstance(config, Mapping) or "_target_" not in config:
        keys = sorted(config) if isinstance(config, Mapping) else type(config).__name__
        raise error(f"{group} config: no _target_ (the {group} class), got keys {keys}")
    built = hydra.utils.instantiate(dict(config), _convert_="all")
    if not isinstance(built, base):
        raise error(
            f"{group} config: _target_ {config['_target_']!r} built a {type(built).__name__}, "
            f"expected a {base.__module__.rsplit('.', 1)[0]}.{base.__name__}"
        )
    return built
