"""No import cycle among ``rigmap`` modules or among its packages, and no over-long function.

The import graph is read from the source with ``ast``: every ``import`` and
``from … import`` counts, at module level or inside a function (a lazy import
hides a cycle from Python, not from a reader), relative imports are resolved,
and ``from package import name`` leads to ``package.name`` when that is a module
and to the package's ``__init__`` otherwise (its re-exports count).

Between packages, each top-level package of ``rigmap`` (``rigmap.rigs`` …) is one
node holding all its modules, and each top-level module (``rigmap.cli``) is its own:
a package cycle with no module cycle is still two layers that need each other. The
applications (``APPLICATIONS``) may import anything; nothing imports them.
"""

from __future__ import annotations

import ast
import itertools
from pathlib import Path

# the one walk over function bodies, shared with scripts/code_shape.py (and its 80-line limit)
from test_code_shape import code_shape

function_lengths = code_shape.function_lengths
MAX_FUNCTION_LINES = code_shape.MAX_FUNCTION_LINES

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "rigmap"

# Parts of the import graph allowed to form a cycle, and functions allowed over 80 lines
# outside rig builders and motion-library clips ("module:qualified name"): none.
ALLOWED_CYCLES: list[frozenset[str]] = []
ALLOWED_LONG_FUNCTIONS: set[str] = set()

# The command line, the jobs it runs and the application layer that reads config (rigmap.app):
# they import the library; the library never imports
# them back (ours: the layering rule of issue #35).
APPLICATIONS = (
    "rigmap.cli",
    "rigmap.learn",
    "rigmap.reproduce",
    "rigmap.app",
    "rigmap.pipeline_params",
    "rigmap.stage",  # the old name of rigmap.app.stage, a re-export
)

LONG_FUNCTIONS_ALLOWED_UNDER = ("rigmap/rigs/characters/", "rigmap/animation/library/")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The rigmap modules ``name`` imports anywhere in its body."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                for alias in node.names
            ]
        else:
            continue
        for target in targets:
            while target and target not in modules:  # `import a.b.c` of a name inside a.b
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected parts with more than one module (each one a cycle)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    parts: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                parts.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return parts


def one_cycle(graph: dict[str, set[str]], part: list[str]) -> list[str]:
    """A shortest import path from the part's first module back to itself."""
    start, members = part[0], set(part)
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        following = []
        for v in frontier:
            for w in sorted(graph[v] & members):
                if w == start:
                    return [*paths[v], start]
                if w not in paths:
                    paths[w] = [*paths[v], w]
                    following.append(w)
        frontier = following
    raise AssertionError(f"{part} is not a cycle")


def test_the_graph_reader_sees_lazy_relative_and_reexported_imports(tmp_path):
    module = tmp_path / "a.py"
    module.write_text(
        "from . import b\nfrom .. import top\n\n\ndef lazy():\n    from .c import name\n"
        "    import pkg.d.inner\n"
    )
    known = {"pkg": None, "pkg.sub": None, "pkg.sub.a": None, "pkg.sub.b": None}
    known |= {"pkg.sub.c": None, "pkg.d": None}
    assert _imports("pkg.sub.a", module, known) == {"pkg.sub.b", "pkg", "pkg.sub.c", "pkg.d"}
    graph = import_graph()
    assert "rigmap.rigs.registry" in graph["rigmap.rigs"]  # a package __init__ re-export
    assert "rigmap.rigs.base" in graph["rigmap.rigs.registry"]
    assert strongly_connected({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert one_cycle({"a": {"b"}, "b": {"c", "a"}, "c": {"a"}}, ["a", "b", "c"]) == ["a", "b", "a"]


def test_no_import_cycle_among_rigmap_modules():
    graph = import_graph()
    cycles = [p for p in strongly_connected(graph) if frozenset(p) not in ALLOWED_CYCLES]
    described = [" -> ".join(one_cycle(graph, part)) for part in cycles]
    assert not cycles, "import cycles:\n" + "\n".join(
        f"{d}   (part: {', '.join(p)})" for d, p in zip(described, cycles, strict=True)
    )


def top_level(module: str) -> str:
    """The package-graph node of a module: ``rigmap.rigs.blender.rig`` -> ``rigmap.rigs``."""
    return ".".join(module.split(".")[:2])


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Module imports folded onto top-level nodes (the ``rigmap`` root's own re-exports aside:
    every module reaches it by being imported, so it belongs to no layer)."""
    folded: dict[str, set[str]] = {}
    for module, targets in graph.items():
        node = top_level(module)
        folded.setdefault(node, set())
        folded[node] |= {top_level(t) for t in targets} - {node, "rigmap"}
    return folded


def test_the_package_graph_folds_modules_onto_top_level_packages():
    graph = {
        "rigmap": set(),
        "rigmap.a": {"rigmap.a.x"},
        "rigmap.a.x": {"rigmap.b.y"},
        "rigmap.b.y": {"rigmap.c", "rigmap"},
        "rigmap.c": {"rigmap.a.z"},
        "rigmap.a.z": set(),
    }
    folded = package_graph(graph)
    assert folded == {
        "rigmap": set(),
        "rigmap.a": {"rigmap.b"},
        "rigmap.b": {"rigmap.c"},
        "rigmap.c": {"rigmap.a"},
    }
    assert not strongly_connected(graph)  # no module cycle …
    assert strongly_connected(folded) == [["rigmap.a", "rigmap.b", "rigmap.c"]]  # … a package one


def test_no_import_cycle_among_rigmap_packages():
    graph = import_graph()
    packages = package_graph(graph)
    assert {"rigmap.rigs", "rigmap.animation", "rigmap.viz", "rigmap.cli"} <= set(packages)
    cycles = strongly_connected(packages)
    described = []
    for part in cycles:
        hops = one_cycle(packages, part)
        edges = [
            f"{m} -> {t}"
            for a, b in itertools.pairwise(hops)
            for m in sorted(graph)
            if top_level(m) == a
            for t in sorted(graph[m])
            if top_level(t) == b
        ]
        described.append(" -> ".join(hops) + "\n    " + "\n    ".join(edges))
    assert not cycles, "import cycles between packages:\n" + "\n".join(described)


def test_no_library_module_imports_an_application():
    graph = import_graph()
    offenders = sorted(
        f"{m} -> {t}"
        for m, targets in graph.items()
        for t in targets
        if top_level(t) in APPLICATIONS and top_level(m) not in APPLICATIONS
    )
    assert not offenders, "library modules importing an application:\n" + "\n".join(offenders)


def _long_functions() -> list[tuple[str, int]]:
    found = []
    for name, path in _modules().items():
        relative = path.relative_to(SRC).as_posix()
        if relative.startswith(LONG_FUNCTIONS_ALLOWED_UNDER):
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        found += [(f"{name}:{q}", n) for q, n in function_lengths(tree) if n > MAX_FUNCTION_LINES]
    return found


def test_no_function_over_80_lines_outside_rig_builders_and_clips():
    offenders = [(q, n) for q, n in _long_functions() if q not in ALLOWED_LONG_FUNCTIONS]
    assert not offenders, "functions over 80 lines:\n" + "\n".join(
        f"{q}: {n} lines" for q, n in offenders
    )
