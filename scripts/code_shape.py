"""Count `# fmt: skip` lines and functions over 80 lines, as ruff formats them, per file.

Issue #35 asks for no `# fmt: skip` outside data tables and no function over 80 lines "as the
formatter lays it out": a function squeezed onto fewer lines by `# fmt: skip` must still count
as long. So each file is measured twice: its `# fmt: skip` comments are counted as written, and
its function lengths are measured on the text `ruff format` gives once those comments are gone.

Usage: python scripts/code_shape.py [PATH ...]  (default: src/rigmap); prints JSON.
"""

from __future__ import annotations

import argparse
import ast
import io
import json
import re
import subprocess
import sys
import tokenize
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"

# The 80-line limit is ours (house rule of issue #35); tests/test_import_graph.py reads it
# and function_lengths from here.
MAX_FUNCTION_LINES = 80

# Data tables exempt from both counts: motion-library clips and rig builders (issue #35).
ALLOWED_UNDER = ("rigmap/animation/library/", "rigmap/rigs/characters/")

FMT_SKIP = re.compile(r"#\s*fmt:\s*skip\b")


@dataclass
class FileShape:
    """What one file holds against the two house rules."""

    path: str
    fmt_skip_lines: int = 0
    long_functions: dict[str, int] = field(default_factory=dict)


def allowed(path: Path) -> bool:
    """True for the data-table folders the rules exempt."""
    relative = path.resolve().as_posix()
    return any(f"/src/{part}" in relative for part in ALLOWED_UNDER)


def ruff_format(source: str, filename: str) -> str:
    """Return `source` as `ruff format` lays it out, with this project's settings."""
    config = ["--config", str(ROOT / "pyproject.toml")]  # whatever folder the file is in
    done = subprocess.run(
        [sys.executable, "-m", "ruff", "format", *config, "--stdin-filename", filename, "-"],
        input=source,
        capture_output=True,
        text=True,
        cwd=ROOT,
        check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"error: ruff format failed on {filename}: {done.stderr.strip()}")
    return done.stdout


def function_lengths(tree: ast.AST, prefix: str = ""):
    """Yield (qualified name, lines) for every function, decorators included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            qualified = f"{prefix}{node.name}"
            if not isinstance(node, ast.ClassDef):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                yield qualified, node.end_lineno - first + 1
            yield from function_lengths(node, f"{qualified}.")


def fmt_skip_comments(source: str) -> dict[int, int]:
    """Line number → column of each `# fmt: skip` comment (comments only, not strings that
    mention one)."""
    tokens = tokenize.generate_tokens(io.StringIO(source).readline)
    return {
        t.start[0]: t.start[1]
        for t in tokens
        if t.type == tokenize.COMMENT and FMT_SKIP.search(t.string)
    }


def without_fmt_skip(source: str, comments: dict[int, int]) -> str:
    """Drop every `# fmt: skip` comment so the formatter lays those lines out too."""
    return "\n".join(
        line[: comments[n]].rstrip() if n in comments else line
        for n, line in enumerate(source.splitlines(), start=1)
    )


def shape_of(path: Path) -> FileShape:
    """Measure one file."""
    source = path.read_text(encoding="utf-8")
    comments = fmt_skip_comments(source)
    formatted = ruff_format(without_fmt_skip(source, comments) + "\n", str(path))
    tree = ast.parse(formatted, filename=str(path))
    long = {q: n for q, n in function_lengths(tree) if n > MAX_FUNCTION_LINES}
    return FileShape(str(path), len(comments), long)


def python_files(paths: list[Path]) -> list[Path]:
    """Every .py file under `paths`, outside the exempt data-table folders."""
    found: list[Path] = []
    for path in paths:
        if not path.exists():
            raise SystemExit(f"error: path: {path} does not exist")
        found += [path] if path.is_file() else sorted(path.rglob("*.py"))
    return [p for p in found if p.suffix == ".py" and not allowed(p)]


def report(paths: list[Path]) -> dict:
    """The JSON summary: totals, then each file that breaks a rule."""
    shapes = [shape_of(p) for p in python_files(paths)]
    offenders = [s for s in shapes if s.fmt_skip_lines or s.long_functions]
    return {
        "files": len(shapes),
        "fmt_skip_lines": sum(s.fmt_skip_lines for s in shapes),
        "long_functions": sum(len(s.long_functions) for s in shapes),
        "max_function_lines": MAX_FUNCTION_LINES,
        "offenders": {
            s.path: {"fmt_skip_lines": s.fmt_skip_lines, "long_functions": s.long_functions}
            for s in offenders
        },
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", type=Path, default=[SRC / "rigmap"])
    args = parser.parse_args(argv)
    print(json.dumps(report(args.paths), indent=2))


if __name__ == "__main__":
    main()
