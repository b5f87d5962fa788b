"""Hydra multirun through the joblib launcher: stages in parallel processes, same files.

A sweep over rigs with ``hydra/launcher=joblib`` must write what the same
stage writes run alone with Hydra's basic launcher, byte for byte (the
corpus is seeded), so a parallel sweep changes the wall time, not a result.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


BIN = Path(sys.executable).parent


def _run(command: list[str], cwd: Path, *, check: bool = False) -> subprocess.CompletedProcess:
    """``command`` with the project's environment first on PATH and its code importable."""
    env = {
        **os.environ,
        "PATH": f"{BIN}:{os.environ.get('PATH', '')}",
        "PYTHONPATH": f"{ROOT / 'src'}:{ROOT / 'pipelines'}",
    }
    return subprocess.run(
        command, cwd=cwd, env=env, capture_output=True, text=True, check=check, timeout=600
    )


def _animate(*overrides: str) -> subprocess.CompletedProcess:
    return _run([sys.executable, str(ROOT / "pipelines" / "animate.py"), *overrides], ROOT)


def test_joblib_multirun_writes_what_single_runs_write(tmp_path):
    swept = _animate(
        "-m",
        "hydra/launcher=joblib",
        "hydra.launcher.n_jobs=2",
        "rig=face,squirrel",
        f"paths.data={tmp_path / 'swept'}",
        f"hydra.sweep.dir={tmp_path / 'multirun'}",
    )
    assert swept.returncode == 0, swept.stderr[-2000:]
    alone = _animate(
        "rig=face",
        f"paths.data={tmp_path / 'alone'}",
        f"hydra.run.dir={tmp_path / 'run'}",
    )
    assert alone.returncode == 0, alone.stderr[-2000:]

    for split in ("train", "test"):
        swept_file = tmp_path / "swept" / "face" / "corpus" / f"{split}.parquet"
        alone_file = tmp_path / "alone" / "face" / "corpus" / f"{split}.parquet"
        assert swept_file.read_bytes() == alone_file.read_bytes()
        assert (tmp_path / "swept" / "squirrel" / "corpus" / f"{split}.parquet").stat().st_size
    sweep = yaml.safe_load((tmp_path / "multirun" / "multirun.yaml").read_text())
    assert sweep["hydra"]["launcher"]["_target_"].endswith("JoblibLauncher")
    assert sweep["hydra"]["launcher"]["n_jobs"] == 2
    # one job folder per swept value
    assert sorted(p.name for p in (tmp_path / "multirun").iterdir() if p.is_dir()) == ["0", "1"]


def _dvc(project: Path, *args: str) -> subprocess.CompletedProcess:
    return _run([str(BIN / "dvc"), *args], project, check=True)


def test_dvc_queue_runs_a_two_point_sweep_in_parallel(tmp_path):
    """The README's `dvc exp run --queue -S …` then `dvc queue start -j 2`, on a one-stage
    project that composes the repository's conf/ (DVC's Hydra integration)."""
    from rigmap.pipeline_params import write_params

    project = tmp_path / "project"
    shutil.copytree(ROOT / "conf", project / "conf")
    (project / "dvc.yaml").write_text(
        "stages:\n"
        "  samples:\n"
        "    cmd: python -c \"open('n.txt','w').write('${budget.samples}')\"\n"
        "    outs: [n.txt]\n"
    )
    (project / ".gitignore").write_text("n.txt\n")
    git = ["git", "-c", "user.name=rigmap-test", "-c", "user.email=test@localhost"]
    subprocess.run(["git", "init", "-q"], cwd=project, check=True)
    _dvc(project, "init", "-q")
    _dvc(project, "config", "hydra.enabled", "true")
    write_params(project, [])
    subprocess.run(["git", "add", "-A"], cwd=project, check=True)
    subprocess.run([*git, "commit", "-qm", "sweep"], cwd=project, check=True)

    for samples in (3, 5):
        _dvc(project, "exp", "run", "--queue", "-S", f"budget.samples={samples}", "-q")
    _dvc(project, "queue", "start", "-j", "2")
    deadline = time.monotonic() + 300
    while True:
        status = _dvc(project, "queue", "status").stdout
        if not any(word in status for word in ("Queued", "Running")):
            break
        assert time.monotonic() < deadline, f"the queue did not finish:\n{status}"
        time.sleep(2)
    assert status.count("Success") == 2, status

    shown = json.loads(_dvc(project, "exp", "show", "--json").stdout)
    runs = {
        rev["name"]: rev["data"]["params"]["params.yaml"]["data"]["budget"]["samples"]
        for commit in shown
        for experiment in commit.get("experiments") or []
        for rev in experiment["revs"]
    }
    assert sorted(runs.values()) == [3, 5]
    for name, samples in runs.items():  # each experiment's own output, applied to the workspace
        _dvc(project, "exp", "apply", name)
        assert (project / "n.txt").read_text() == str(samples)
