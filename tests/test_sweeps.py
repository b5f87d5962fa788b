"""Hydra multirun through the joblib launcher: stages in parallel processes, same files.

A sweep over rigs with ``hydra/launcher=joblib`` must write what the same
stage writes run alone with Hydra's basic launcher, byte for byte (the
corpus is seeded), so a parallel sweep changes the wall time, not a result.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
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


def _start_queue_workers(project: Path, *, jobs: int) -> None:
    """``dvc queue start`` with its output in a file, not a pipe.

    DVC forks each worker from the command's own process, so a worker holds
    the command's stdout and stderr open until it shuts down (a minute after
    the queue empties, or never if it hangs): reading them through a pipe
    would wait on the workers, not on the command."""
    log = project / "queue-start.log"
    env = {**os.environ, "PATH": f"{BIN}:{os.environ.get('PATH', '')}"}
    with log.open("wb") as output:
        started = subprocess.run(
            [str(BIN / "dvc"), "queue", "start", "-j", str(jobs)],
            cwd=project,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=output,
            stderr=subprocess.STDOUT,
            timeout=120,
        )
    assert started.returncode == 0, log.read_text()


def _worker_pids(project: Path) -> list[int]:
    """The queue workers' process ids, from the pid files DVC writes beside their logs."""
    return [int(p.read_text()) for p in (project / ".dvc" / "tmp").rglob("dvc-exp-worker-*.pid")]


def _worker_logs(project: Path) -> str:
    logs = sorted((project / ".dvc" / "tmp").rglob("dvc-exp-worker-*.out"))
    return "\n".join(f"--- {p.name}\n{p.read_text()[-2000:]}" for p in logs)


def _stop_queue_workers(project: Path) -> None:
    """End the workers now rather than after their idle timeout, so none outlives the test."""
    for pid in _worker_pids(project):
        try:
            os.kill(pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(_alive(pid) for pid in _worker_pids(project)):
        time.sleep(0.5)
    for pid in _worker_pids(project):
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_dvc_queue_runs_a_two_point_sweep_in_parallel(tmp_path):
    """The README's `dvc exp run --queue -S …` then `dvc queue start -j 2`, on a one-stage
    project that composes the repository's conf/ (DVC's Hydra integration)."""
    from rigmap.app.params import write_params

    project = tmp_path / "project"
    shutil.copytree(ROOT / "conf", project / "conf")
    (project / "dvc.yaml").write_text(
        "stages:\n"
        "  samples:\n"
        "    cmd: python -c \"open('n.txt','w').write('${budget.samples}')\"\n"
        "    outs: [n.txt]\n"
    )
    (project / ".gitignore").write_text("n.txt\n")
    subprocess.run(["git", "init", "-q"], cwd=project, check=True)
    # DVC commits each experiment and `exp apply` stashes: both need an identity,
    # which a CI machine may not have globally.
    for key, value in (("user.name", "rigmap-test"), ("user.email", "test@localhost")):
        subprocess.run(["git", "config", key, value], cwd=project, check=True)
    _dvc(project, "init", "-q")
    _dvc(project, "config", "hydra.enabled", "true")
    write_params(project, [])
    subprocess.run(["git", "add", "-A"], cwd=project, check=True)
    subprocess.run(["git", "commit", "-qm", "sweep"], cwd=project, check=True)

    for samples in (3, 5):
        _dvc(project, "exp", "run", "--queue", "-S", f"budget.samples={samples}", "-q")
    try:
        _start_queue_workers(project, jobs=2)
        deadline = time.monotonic() + 300
        while True:
            status = _dvc(project, "queue", "status").stdout
            if not any(word in status for word in ("Queued", "Running")):
                break
            assert time.monotonic() < deadline, (
                f"the queue did not finish:\n{status}\n{_worker_logs(project)}"
            )
            time.sleep(2)
    finally:
        _stop_queue_workers(project)
    assert status.count("Success") == 2, f"{status}\n{_worker_logs(project)}"

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
