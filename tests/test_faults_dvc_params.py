"""A value with shell syntax in params.yaml is stopped before any DVC stage command runs it.

Issue 20, defect 3: values reached DVC's stage commands unquoted (``corpus.variation=${…}``), so
``1.0;touch PWNED`` in params.yaml (from ``dvc exp run -S`` or a hand edit, which bypass
``rigmap reproduce``'s checks) ran ``touch``. The ``check_params`` stage, on which every stage
depends, refuses the file first; since issue 36 the commands name their values
(``corpus.variation=@corpus.variation``) and no value reaches a shell even without it
(tests/test_fault_cli.py, under ``dvc repro --single-item``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

from stage_scripts import copy_stage_files

ROOT = Path(__file__).resolve().parents[1]


def _project(tmp_path: Path, **changes) -> Path:
    """A copy of the pipeline (stage files, conf/, params.yaml; code linked) with ``changes``."""
    project = tmp_path / "project"
    project.mkdir()
    copy_stage_files(project)
    shutil.copy(ROOT / "params.yaml", project / "params.yaml")
    shutil.copytree(ROOT / "conf", project / "conf")
    for name in ("src", "pipelines"):
        (project / name).symlink_to(ROOT / name)
    params = yaml.safe_load((project / "params.yaml").read_text())
    for dotted, value in changes.items():
        node = params
        *parents, leaf = dotted.split(".")
        for key in parents:
            node = node[key]
        node[leaf] = value
    (project / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    _dvc(project, "init", "--no-scm", "-q")
    return project


def _dvc(project: Path, *args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    return subprocess.run([sys.executable, "-m", "dvc", *args], cwd=project, env=env,
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def test_shell_syntax_in_params_yaml_never_reaches_a_stage_command(tmp_path):
    project = _project(tmp_path, **{"corpus.variation": "1.0;touch PWNED"})
    done = _dvc(project, "repro", "stages/data/dvc.yaml:animate@quadruped")
    assert done.returncode != 0
    output = done.stdout + done.stderr
    assert "refused before any stage ran" in output, output[-2000:]
    assert "corpus.variation = '1.0;touch PWNED'" in output
    assert not (project / "PWNED").exists()
    assert not (project / "data" / "quadruped").exists()  # the animate command never ran


def test_a_sound_params_yaml_passes_with_a_stamp_that_never_changes(tmp_path):
    project = _project(tmp_path)
    done = _dvc(project, "repro", "check_params")
    assert done.returncode == 0, (done.stdout + done.stderr)[-2000:]
    assert (project / "data" / "params_checked.txt").read_text() == "params.yaml checked\n"
