"""Which rigs exist and how to build them, by name.

Backends register a factory under a name; ``load`` builds the rig from a name
or a config mapping (``{"name": ..., **options}``, e.g. a Hydra ``rig`` group).
Factories are imported lazily so listing rigs never starts Blender.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from functools import cache

from rigmap.rigs.base import Rig, UnknownRigError

# name -> "module:callable"; the callable takes keyword options and returns a Rig.
_FACTORIES: dict[str, str] = {
    "quadruped": "rigmap.rigs.characters.quadruped:build_quadruped",
    "biped": "rigmap.rigs.characters.biped:build_biped",
    "face": "rigmap.rigs.characters.face:build_face",
    "squirrel": "rigmap.rigs.characters.squirrel:build_squirrel",
    "rigify_human": "rigmap.rigs.blender.rigify:build_rigify_human",
    "rigify_wolf": "rigmap.rigs.blender.rigify:build_rigify_wolf",
    "blend_file": "rigmap.rigs.blender.rigify:build_blend_file",
}


def register(name: str, factory: str | Callable[..., Rig]) -> None:
    """Make ``load(name)`` build a rig with ``factory`` ("module:callable" or a callable)."""
    _FACTORIES[name] = factory  # type: ignore[assignment]
    _cached_builtin.cache_clear()


def available() -> list[str]:
    """Names ``load`` accepts."""
    return sorted(_FACTORIES)


def load(name_or_config: str | Mapping | Rig, **overrides) -> Rig:
    """Build (or fetch from cache) the rig named by a string or a config mapping."""
    if isinstance(name_or_config, Rig):
        return name_or_config
    if isinstance(name_or_config, str):
        name, options = name_or_config, {}
    else:
        options = {k: v for k, v in dict(name_or_config).items() if not k.startswith("_")}
        if "name" not in options:
            raise UnknownRigError(f"rig config has no 'name' field: keys {sorted(options)}")
        name = options.pop("name")
    options.update(overrides)
    if name not in _FACTORIES:
        raise UnknownRigError(f"unknown rig {name!r}; available rigs: {', '.join(available())}")
    if not options:
        return _cached_builtin(name)
    return _resolve(name)(**_plain(options))


@cache
def _cached_builtin(name: str) -> Rig:
    return _resolve(name)()


def _resolve(name: str) -> Callable[..., Rig]:
    factory = _FACTORIES[name]
    if callable(factory):
        return factory
    module, _, attr = factory.partition(":")
    return getattr(importlib.import_module(module), attr)


def _plain(options: Mapping) -> dict:
    """OmegaConf containers to plain Python, so factories see dicts and lists."""
    try:
        from omegaconf import DictConfig, ListConfig, OmegaConf

        return {
            k: OmegaConf.to_container(v, resolve=True)
            if isinstance(v, DictConfig | ListConfig)
            else v
            for k, v in options.items()
        }
    except ImportError:  # pragma: no cover - omegaconf is a dependency
        return dict(options)
