"""One catalogue of the names of methods, samplers and kernels, and the labels reports print.

Each part says its own label once: a method in its yaml (``extra:`` and its guess's
``title:`` in ``conf/method/<name>.yaml``; a refiner adds `` & `` and its class's title), a
sampler or a kernel on its class (``title`` and ``extra`` attributes of the yaml's ``_target_``).
The order is the evaluate group's lists
(``conf/evaluate/default.yaml``: the order of the paper's tables; what a report expects by
default), then any other yaml of the group by name. Reports, figures and the evaluation ask
this module, so a new part is its class and its yaml; a name it does not know prints as itself.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import yaml

from rigmap.errors import RigmapError
from rigmap.store.layout import packaged_conf  # re-exported: the package's own conf/

#: the config groups the catalogue reads, and the evaluate list that orders each
KINDS = ("method", "sampler", "kernel")
_LISTS = {"method": "methods", "sampler": "samplers", "kernel": "kernels"}


class CatalogueError(RigmapError, ValueError):
    """A part's yaml or class that does not say its label in the expected form."""


@dataclass(frozen=True)
class Row:
    """One row kind of a table: its key (in metrics file names), printed label, paper or not."""

    key: str
    label: str
    extra: bool = False  # a row the paper does not have
    regressor: str | None = None  # a method's fitted mapping (its model folder's first part)

    @property
    def display(self) -> str:
        return f"{self.label} (extra)" if self.extra else self.label


@dataclass(frozen=True)
class Catalogue:
    """The rows of every kind, in table order."""

    methods: tuple[Row, ...] = ()
    samplers: tuple[Row, ...] = ()
    kernels: tuple[Row, ...] = ()
    #: per kind, the names the evaluate lists run (what a report expects by default)
    listed: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def rows(self, kind: str) -> tuple[Row, ...]:
        if kind not in KINDS:
            raise CatalogueError(f"catalogue: kind must be one of {KINDS}, got {kind!r}")
        return getattr(self, _LISTS[kind])

    def row(self, kind: str, key: str) -> Row:
        """The row ``key`` of ``kind``; a name not catalogued is labelled by itself."""
        for row in self.rows(kind):
            if row.key == key:
                return row
        return Row(str(key), str(key))

    def method(self, key: str) -> Row:
        return self.row("method", key)

    def sampler(self, key: str) -> Row:
        return self.row("sampler", key)

    def kernel(self, key: str) -> Row:
        return self.row("kernel", key)

    def keys(self, kind: str) -> tuple[str, ...]:
        """The names the evaluate lists run, in table order (all rows if nothing is listed)."""
        listed = self.listed.get(kind)
        return tuple(listed) if listed else tuple(row.key for row in self.rows(kind))


@lru_cache(maxsize=1)
def default_catalogue() -> Catalogue:
    """The catalogue of the package's own config folder (read once per process)."""
    return read_catalogue([packaged_conf()])


def read_catalogue(folders: Sequence[str | Path]) -> Catalogue:
    """The catalogue of config folders (the project's, then e.g. Hydra search-path folders).

    A later folder adds its parts after the earlier ones' and may relabel a name.
    """
    folders = [Path(f) for f in folders]
    missing = [str(f) for f in folders if not f.is_dir()]
    if missing:
        raise CatalogueError(f"catalogue: config folders {missing} do not exist")
    rows: dict[str, Any] = {"listed": {}}
    for kind in KINDS:
        listed = _listed_names(folders, kind)
        rows["listed"][kind] = tuple(listed)
        order = [*listed, *[n for f in folders for n in _group_files(f, kind) if n not in listed]]
        found: dict[str, Row] = {}
        for folder in folders:
            for name, path in _group_files(folder, kind).items():
                found[name] = _row(kind, name, path, folders)
        rows[_LISTS[kind]] = tuple(found[name] for name in order if name in found)
    return Catalogue(**rows)


def _group_files(folder: Path, kind: str) -> dict[str, Path]:
    group = folder / kind
    return {p.stem: p for p in sorted(group.glob("*.yaml"))} if group.is_dir() else {}


def _listed_names(folders: Iterable[Path], kind: str) -> list[str]:
    """The names of the evaluate lists (``evaluate/default.yaml``), in their order."""
    names: list[str] = []
    for folder in folders:
        lists = folder / "evaluate" / "default.yaml"
        if lists.is_file():
            listed = (_load(lists) or {}).get(_LISTS[kind]) or []
            names += [str(n) for n in listed if str(n) not in names]
    return names


def _load(path: Path) -> Any:
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise CatalogueError(f"{path}: not valid yaml ({error})") from None


def _row(kind: str, name: str, path: Path, folders: Sequence[Path]) -> Row:
    """A sampler's or kernel's label from its ``_target_`` class; a method's from its yaml."""
    node = _load(path)
    if not isinstance(node, Mapping):
        raise CatalogueError(f"{path}: expected a mapping, got {type(node).__name__}")
    regressor = None
    if kind == "method":
        title, extra = _method_title(path, node, folders), node.get("extra")
        guess = node.get("guess")
        regressor = guess.get("regressor") if isinstance(guess, Mapping) else None
    else:
        source = _target_class(path, node)
        title, extra = getattr(source, "title", None), getattr(source, "extra", None)
    if title is not None and not isinstance(title, str):
        raise CatalogueError(f"{path}: title must be a string, got {title!r}")
    if extra is not None and not isinstance(extra, bool):
        raise CatalogueError(f"{path}: extra must be true or false, got {extra!r}")
    return Row(name, title or name, bool(extra), regressor)


def _method_title(path: Path, node: Mapping[str, Any], folders: Sequence[Path]) -> str | None:
    """The guess's ``title``, then `` & `` and what its refine group's class adds (if any),
    as :attr:`rigmap.evaluation.method.Method.title` says it once the method is built."""
    guess = node.get("guess")
    if not isinstance(guess, Mapping):
        return None
    title = guess.get("title", guess.get("regressor"))
    entries = [e for e in node.get("defaults") or [] if isinstance(e, Mapping)]
    choices = [e["/refine@refine"] for e in entries if "/refine@refine" in e]
    files = [f / "refine" / f"{c}.yaml" for c in choices[:1] for f in reversed(list(folders))]
    refine_file = next((f for f in files if f.is_file()), None)
    refine = dict(node.get("refine") or {})  # the method's own node over its group's yaml
    if refine_file is not None:
        refine = {**(_load(refine_file) or {}), **refine}
    if title is None or "_target_" not in refine:
        return title
    added = _target_class(refine_file or path, refine).title_of(refine)
    return title if added is None else f"{title} & {added}"


def _target_class(path: Path, node: Mapping[str, Any]) -> Any:
    """The class a sampler or kernel yaml names (imported, as instantiating it would)."""
    target = node.get("_target_")
    if not isinstance(target, str) or "." not in target:
        raise CatalogueError(f"{path}: _target_ must name a class (module.Class), got {target!r}")
    module, _, attribute = target.rpartition(".")
    try:
        return getattr(importlib.import_module(module), attribute)
    except (ImportError, AttributeError) as error:
        raise CatalogueError(f"{path}: _target_ {target!r} cannot be imported ({error})") from None
