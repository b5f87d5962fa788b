"""Which rigs exist and how to build them, by name.

Each rig's :class:`~rigmap.rigs.manifest.RigManifest` names its factory; ``load``
builds the rig from a name or a plain config mapping (``{"name": ..., **options}``, e.g.
a Hydra ``rig`` group the application layer turned into dicts and lists). Factories are
imported lazily so listing rigs never starts Blender.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from functools import cache

from rigmap.rigs.base import Rig, UnknownRigError
from rigmap.rigs.manifest import (
    RigManifest,
    all_manifests,
    manifest,
    register_manifest,
    resolve,
)


def register(name: str | RigManifest, factory: str | Callable[..., Rig] | None = None) -> None:
    """Make ``load(name)`` build a rig with ``factory`` ("module:callable" or a callable).

    A :class:`~rigmap.rigs.manifest.RigManifest` may be passed instead, telling every
    consumer about the rig at once; a bare factory keeps the rest of a known rig's manifest.
    """
    if isinstance(name, RigManifest):
        register_manifest(name)
        return
    if factory is None:
        raise TypeError(f"register({name!r}) needs a factory or a RigManifest")
    known = all_manifests().get(name)
    if known is None:
        register_manifest(RigManifest(name=name, factory=factory, label=name))
    else:
        register_manifest(replace(known, factory=factory))


def available() -> list[str]:
    """Names ``load`` accepts."""
    return sorted(all_manifests())


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
    known = manifest(name)  # unknown names fail here, before building
    if not options:
        return _cached_builtin(known.factory)
    return known.build_factory()(**options)


@cache
def _cached_builtin(factory: str | Callable[..., Rig]) -> Rig:
    """One rig per factory (a re-registered name builds afresh)."""
    return resolve(factory)()


def use_executor(rig, executor: dict | None):
    """Switch a Blender rig to ``executor``; ``local`` suits every rig, ``ray`` Blender rigs."""
    from rigmap.errors import RigmapError

    kind = (executor or {}).get("kind", "local")
    if hasattr(rig, "use_executor"):
        rig.use_executor(executor)
    elif kind != "local":
        raise RigmapError(
            f"executor={kind} evaluates Blender rigs (rigify_human, rigify_wolf, blend_file) on "
            f"workers; rig {rig.name!r} is evaluated in this process: use executor=local"
        )
    return rig
