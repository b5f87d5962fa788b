"""Hydra multirun through the joblib launcher: stages in parallel processes, same files.

A sweep over rigs with ``hydra/launcher=joblib`` must write what the same
stage writes run alone with Hydra's basic launcher, byte for byte (the
corpus is seeded), so a parallel sweep changes the wall time, not a result.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def _animate(tmp: Path, *overrides: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": f"{ROOT / 'src'}:{ROOT / 'pipelines'}"}
    return subprocess.run(
        [sys.executable, str(ROOT / "pipelines" / "animate.py"), *overrides],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_joblib_multirun_writes_what_single_runs_write(tmp_path):
    swept = _animate(
        tmp_path,
        "-m",
        "hydra/launcher=joblib",
        "hydra.launcher.n_jobs=2",
        "rig=face,squirrel",
        f"paths.data={tmp_path / 'swept'}",
        f"hydra.sweep.dir={tmp_path / 'multirun'}",
    )
    assert swept.returncode == 0, swept.stderr[-2000:]
    alone = _animate(
        tmp_path,
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
