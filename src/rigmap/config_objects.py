"""Objects built from config nodes: ``hydra.utils.instantiate``, then checked to be the kind
the caller asked for, so a wrong ``_target_`` is one clear error naming the group.

The one module outside :mod:`rigmap.app` that imports Hydra, because two library callers
still build from config nodes and cannot import the application layer without a cycle:
``rigmap.map.subset_model`` (its regressor) and ``rigmap.evaluation.method``'s
``packaged_methods`` (the package's ``conf/method``, for the runner and the sample sweep,
which take a method by name). It joins :mod:`rigmap.app.objects` once they take built
objects. The application layer uses it through :mod:`rigmap.app.objects`."""

from __future__ import annotations

import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError

#: Hydra keeps one initialised state per process (GlobalHydra): two threads composing at
#: once (two studio pages loading rigs) would see each other's; every composition holds this
HYDRA_LOCK = threading.RLock()


class ConfigNodeError(RigmapError, ValueError):
    """A config node Hydra could not build; ``__cause__`` is the reason Hydra wrapped."""


def instantiate_node(config: Mapping[str, Any], **kwargs: Any) -> Any:
    """``hydra.utils.instantiate`` of a plain node (``kwargs`` added to its own), Hydra's
    wrapper unwrapped so the caller names the reason plainly."""
    import hydra.utils
    from hydra.errors import InstantiationException

    try:
        return hydra.utils.instantiate(dict(config), _convert_="all", **kwargs)
    except InstantiationException as error:
        cause = error.__cause__ if error.__cause__ is not None else error
        raise ConfigNodeError(str(cause)) from cause


def compose_group(config_dir: Path, group: str) -> Any:
    """The ``group`` node of ``config_dir``'s ``config.yaml`` as composed, plain and resolved."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.initialize import get_gh_backup, restore_gh_from_backup
    from omegaconf import OmegaConf

    with HYDRA_LOCK:
        running_app = get_gh_backup()  # inside a stage's @hydra.main Hydra is initialised
        GlobalHydra.instance().clear()
        try:
            with initialize_config_dir(config_dir=str(config_dir), version_base="1.3"):
                config = compose(config_name="config")
        finally:
            restore_gh_from_backup(running_app)
    return OmegaConf.to_container(config[group], resolve=True)


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
