"""Two pipeline stages side by side, on torch's and numpy's default thread pools against one
thread each (what ``rigmap reproduce`` sets, :data:`rigmap.reproduce.STAGE_THREADS`).

Prints JSON: per mode and repeat, each stage's wall seconds and the pair's. The stages are
real stage commands on the project's reproduced data (run ``make reproduce`` first), writing
into a temporary folder: the joint-space fit up to its posed draws (no training epochs) and
a GMM supersample of the biped at the quick budget (4 000 samples). The modes alternate, so
a change in the machine's load hits both alike.

    .venv/bin/python benchmarks/stage_threads.py [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rigmap.reproduce import STAGE_THREADS

ROOT = Path(__file__).resolve().parents[1]
STAGES = {
    "joint_space_fit_draws": [
        "pipelines/fit.py", "rig=biped", "regressor=nn_joint_space", "sampler=none",
        "regressor.epochs=0", "regressor.pretrain_epochs=0", "regressor.progress=false",
    ],
    "supersample_gmm": [
        "pipelines/supersample.py", "rig=biped", "sampler=gmm", "budget.samples=4000",
    ],
}  # fmt: skip


def side_by_side(env: dict[str, str], scratch: Path) -> dict[str, float]:
    """Start every stage at once; each one's wall seconds and the pair's."""
    began, running = time.perf_counter(), {}
    for name, argv in STAGES.items():
        out = scratch / name
        rig_data = out / "data" / "biped"  # the inputs linked, the outputs written here
        rig_data.mkdir(parents=True)
        for inputs in ("corpus", "poses"):
            (rig_data / inputs).symlink_to(ROOT / "data" / "biped" / inputs)
        paths = [f"paths.data={out / 'data'}", f"paths.models={out / 'models'}"]
        with (out / "stderr.txt").open("wb") as errors:  # a file: a full pipe would stall it
            running[name] = subprocess.Popen(
                [sys.executable, *argv, *paths],
                cwd=ROOT,
                env=env,
                stdout=subprocess.DEVNULL,
                stderr=errors,
            )
    seconds: dict[str, float] = {}
    while len(seconds) < len(running):  # each stage's own end, whichever ends first
        for name, process in running.items():
            if name not in seconds and process.poll() is not None:
                seconds[name] = round(time.perf_counter() - began, 2)
                if process.returncode != 0:
                    err = (scratch / name / "stderr.txt").read_text(errors="replace")
                    raise SystemExit(f"{name} failed: {err[-800:]}")
        time.sleep(0.05)
    seconds["pair"] = round(time.perf_counter() - began, 2)
    return seconds


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    if not (ROOT / "data" / "biped" / "corpus").is_dir():
        raise SystemExit("data/biped/corpus not found: run `make reproduce` first")
    base = {k: v for k, v in os.environ.items() if k not in STAGE_THREADS}
    modes = {"default_threads": base, "one_thread": {**base, **STAGE_THREADS}}
    runs: dict[str, list[dict[str, float]]] = {mode: [] for mode in modes}
    with tempfile.TemporaryDirectory() as scratch:
        for repeat in range(args.repeats):
            for mode, env in modes.items():
                runs[mode].append(side_by_side(env, Path(scratch) / f"{mode}-{repeat}"))
    print(json.dumps({"cpus": os.cpu_count(), "stages": STAGES, "runs": runs}, indent=2))


if __name__ == "__main__":
    main()
