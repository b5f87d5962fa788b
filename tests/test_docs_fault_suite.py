"""docs/fault-suite.md is generated from the fault tests (scripts/fault_suite.py); a change to
the tests that is not regenerated into the page fails here, as a stale params.yaml does."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _script(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    return subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "fault_suite.py"), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_the_committed_fault_suite_page_is_current(tmp_path):
    done = _script("--check", cwd=tmp_path)  # from any folder
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]
    assert "docs/fault-suite.md is current" in done.stdout


def test_the_page_meets_the_issues_bar_and_names_every_trial():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import fault_suite
    finally:
        sys.path.remove(str(ROOT / "scripts"))
    text = (ROOT / "docs" / "fault-suite.md").read_text()
    bad = int(text.split("- **", 1)[1].split(" bad inputs", 1)[0])
    assert bad >= fault_suite.BAR
    for _, trial, cases in fault_suite.TRIALS:
        row = next(line for line in text.splitlines() if f"| {trial} |" in line)
        assert all(f"::{case}`" in row for case in cases), row
