"""Only the application layer reads config: no module outside ``rigmap.app`` imports Hydra or
omegaconf (issue #35, must-show (b)).

Every module under ``src/rigmap`` is read with ``ast``; an ``import`` or ``from … import``
anywhere in it counts, inside a function too (a lazy import still ties the module to
Hydra). ``rigmap.cli``, the entry, calls the application layer and reads no config itself.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "rigmap"
CONFIG_LIBRARIES = ("omegaconf", "hydra")
APPLICATION_LAYER = "rigmap.app"

#: modules outside the application layer still allowed to import Hydra, with the reason (ours)
KNOWN_EXCEPTIONS = {
    "rigmap.config_objects": "rigmap.map.subset_model builds its regressor from a config node "
    "(instantiate_as) and rigmap.evaluation.method its methods (instantiate_node; "
    "packaged_methods composes the package's conf/method for the runner and the sample "
    "sweep, which take a method by name); it moves into rigmap.app.objects when they take "
    "built objects",
}


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def config_imports(path: Path) -> list[str]:
    """The Hydra/omegaconf modules ``path`` imports anywhere in its body."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names = [node.module]
        else:
            continue
        found += [name for name in names if name.split(".")[0] in CONFIG_LIBRARIES]
    return found


def config_readers(root: Path) -> dict[str, list[str]]:
    """Every module under ``root`` (a ``src`` folder) that imports Hydra or omegaconf."""
    readers = {}
    for path in sorted(root.rglob("*.py")):
        found = config_imports(path)
        if found:
            readers[module_name(path, root)] = found
    return readers


def in_application_layer(module: str) -> bool:
    return module == APPLICATION_LAYER or module.startswith(APPLICATION_LAYER + ".")


def test_the_reader_counts_lazy_and_from_imports_and_nothing_else(tmp_path):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "lazy.py").write_text("def f():\n    from hydra.utils import instantiate\n")
    (package / "top.py").write_text("import omegaconf.errors as e\n")
    (package / "plain.py").write_text("import hydrate\nfrom . import omegaconf\n# import hydra\n")
    assert config_readers(tmp_path) == {
        "pkg.lazy": ["hydra.utils"],
        "pkg.top": ["omegaconf.errors"],
    }


def test_only_the_application_layer_imports_hydra_or_omegaconf():
    readers = config_readers(SRC)
    outside = {
        module: names
        for module, names in readers.items()
        if not in_application_layer(module) and module not in KNOWN_EXCEPTIONS
    }
    assert not outside, "modules outside rigmap.app importing Hydra or omegaconf: " + "; ".join(
        f"{module} ({', '.join(names)})" for module, names in sorted(outside.items())
    )


def test_the_application_layer_is_where_config_is_read():
    readers = config_readers(SRC)
    layer = {module for module in readers if module.startswith(APPLICATION_LAYER + ".")}
    assert {"rigmap.app.config", "rigmap.app.stage", "rigmap.app.inputs"} <= layer


def test_every_known_exception_still_needs_its_allowance():
    readers = config_readers(SRC)
    stale = sorted(set(KNOWN_EXCEPTIONS) - set(readers))
    assert not stale, f"no longer import Hydra or omegaconf, drop from KNOWN_EXCEPTIONS: {stale}"
