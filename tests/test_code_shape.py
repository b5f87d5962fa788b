"""Every package is clean of `# fmt: skip` and of functions over 80 lines, and stays so (#35).

`scripts/code_shape.py` counts both as ruff lays the code out; it reported 0 and 0 over all
of `src/rigmap` once `evaluation/` was cleaned, so the test holds every package and the
top-level modules (a new package is held as soon as it exists).
"""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "rigmap"

#: every package under src/rigmap, read from the tree (`conf` is the config link, no code)
CLEAN_PACKAGES = tuple(
    f"rigmap/{folder.name}"
    for folder in sorted(PACKAGE.iterdir())
    if folder.is_dir() and not folder.is_symlink() and any(folder.rglob("*.py"))
)
TOP_LEVEL_MODULES = tuple(sorted(PACKAGE.glob("*.py")))


def _code_shape():
    spec = importlib.util.spec_from_file_location("code_shape", ROOT / "scripts" / "code_shape.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["code_shape"] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


code_shape = _code_shape()


@pytest.mark.parametrize("package", CLEAN_PACKAGES)
def test_clean_package_has_no_fmt_skip_and_no_long_function(package):
    found = code_shape.report([ROOT / "src" / package])
    assert found["files"] > 0, f"no Python files under src/{package}"
    assert (found["fmt_skip_lines"], found["long_functions"]) == (0, 0), found["offenders"]


def test_every_package_is_held():
    # the packages that were cleaned last, and the one this list once left out
    assert {"rigmap/evaluation", "rigmap/app", "rigmap/map", "rigmap/rigs"} <= set(CLEAN_PACKAGES)
    assert "rigmap/conf" not in CLEAN_PACKAGES


def test_top_level_modules_have_no_fmt_skip_and_no_long_function():
    found = code_shape.report(list(TOP_LEVEL_MODULES))
    assert found["files"] == len(TOP_LEVEL_MODULES) > 10
    assert (found["fmt_skip_lines"], found["long_functions"]) == (0, 0), found["offenders"]


def test_checker_counts_a_squeezed_long_function(tmp_path):
    # 41 lines of two statements kept by `# fmt: skip`: 43 lines as written, 84 as formatted;
    # a string that mentions the comment is not one
    body = "\n".join(f"    a{i} = {i}; b{i} = {i}  # fmt: skip" for i in range(41))
    text = '    note = "# fmt: skip"\n'
    (tmp_path / "squeezed.py").write_text(f"def squeezed():\n{body}\n    return 0\n{text}")
    (tmp_path / "short.py").write_text("def short():\n    return 1\n")
    found = code_shape.report([tmp_path])
    assert found["files"] == 2
    assert found["fmt_skip_lines"] == 41
    assert found["offenders"] == {
        str(tmp_path / "squeezed.py"): {"fmt_skip_lines": 41, "long_functions": {"squeezed": 85}}
    }


def test_checker_leaves_out_data_tables(tmp_path):
    clips = tmp_path / "src" / "rigmap" / "animation" / "library"
    clips.mkdir(parents=True)
    (clips / "clip.py").write_text("x = [1,  2]  # fmt: skip\n")
    assert code_shape.report([tmp_path])["files"] == 0
