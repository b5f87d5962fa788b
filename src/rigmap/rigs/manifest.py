"""What a rig says about itself: one manifest per rig instead of one dict per consumer.

A :class:`RigManifest` names the rig's factory, its motion library, its script
baseline, the label reports print and the view its poses read best in. Every
consumer (``rigmap.rigs.load``, the motion-library lookup, the script baseline,
the report catalogue, the sample figures) asks the manifest, so adding a rig is
its module plus its manifest (plus its ``conf/rig/<name>.yaml``).

Built-in manifests live one per module in :mod:`rigmap.rigs.manifests`, each as
``MANIFEST``; they are found by listing that package. Everything a manifest names
is a ``"module:attribute"`` string resolved on use, so listing rigs imports no
rig (and never starts Blender).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

from rigmap.rigs.base import UnknownRigError


@dataclass(frozen=True)
class RigManifest:
    """Everything about a rig that code outside the rig needs to know.

    ``factory`` and ``script`` are ``"module:callable"`` (or callables); ``library``
    is the module holding the rig's ``LIBRARY`` (a motion library), or ``None``.
    ``report_order`` places the rig in the paper's tables (Table 3's order, then
    the Blender rigs); ``None`` keeps it out of the default report.
    """

    name: str
    factory: str | Callable
    label: str
    library: str | None = None
    script: str | Callable | None = None
    view: str = "side"
    report_order: int | None = None
    extra: bool = False  # a row the paper does not have

    def build_factory(self) -> Callable:
        """The callable that builds the rig from keyword options."""
        return resolve(self.factory)

    def script_function(self) -> Callable | None:
        """The hand-written retarget script, or ``None`` when the rig has none."""
        return None if self.script is None else resolve(self.script)


def character(
    name: str,
    label: str,
    *,
    script: bool = False,
    view: str = "side",
    report_order: int | None = None,
) -> RigManifest:
    """The manifest of a character rigmap builds in-process, whose parts follow one scheme:
    factory ``rigmap.rigs.characters.<name>:build_<name>``, motion library
    ``rigmap.animation.library.<name>`` and, with ``script``, the script baseline
    ``rigmap.retarget.<name>_script:retarget_<name>``."""
    return RigManifest(
        name=name,
        factory=f"rigmap.rigs.characters.{name}:build_{name}",
        label=label,
        library=f"rigmap.animation.library.{name}",
        script=f"rigmap.retarget.{name}_script:retarget_{name}" if script else None,
        view=view,
        report_order=report_order,
    )


_REGISTERED: dict[str, RigManifest] = {}


def resolve(target: str | Callable) -> Callable:
    """``"module:attribute"`` imported and looked up; a callable is returned as it is."""
    if callable(target):
        return target
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


@cache
def _builtin() -> tuple[RigManifest, ...]:
    from rigmap.rigs import manifests

    found = []
    for info in pkgutil.iter_modules(manifests.__path__):
        module = importlib.import_module(f"{manifests.__name__}.{info.name}")
        found.append(module.MANIFEST)
    return tuple(found)


def register_manifest(manifest: RigManifest) -> None:
    """Make a rig known to every consumer (a later manifest of the same name wins)."""
    if not isinstance(manifest, RigManifest):
        raise TypeError(f"register_manifest takes a RigManifest, got {type(manifest).__name__}")
    _REGISTERED[manifest.name] = manifest


def all_manifests() -> dict[str, RigManifest]:
    """Every known rig's manifest by name: the built-in ones, then registered ones."""
    manifests = {m.name: m for m in _builtin()}
    manifests.update(_REGISTERED)
    return manifests


def manifest(name: str) -> RigManifest:
    """The manifest of rig ``name``; a clear error listing the known rigs otherwise."""
    manifests = all_manifests()
    if name not in manifests:
        raise UnknownRigError(
            f"unknown rig {name!r}; available rigs: {', '.join(sorted(manifests))}"
        )
    return manifests[name]


def reported() -> list[RigManifest]:
    """The rigs of the default report, in the paper's table order."""
    rows = [m for m in all_manifests().values() if m.report_order is not None]
    return sorted(rows, key=lambda m: (m.report_order, m.name))
