"""``kill -9`` at points of the pipeline, then the stage re-run (what ``dvc repro`` does).

For each point a real stage runs on the quadruped in a child process and is killed
with SIGKILL once its output says it is mid-way (animate: after the first clip file;
pose: while posing the first split; fit: during network training). Right after the
kill no output may be half-written (each is absent or whole, no stray temporaries);
after the re-run every output is byte-identical to an uninterrupted run's. The
supersample kill point lives in ``test_supersample.py`` and the Blender worker kill in
``test_blender_pool.py``; they are not repeated here.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
STAGES = {
    # stage: (its arguments, output files under the run folder, the line that means "mid-way")
    "animate": (
        ["pipelines/animate.py", "rig=quadruped"],
        ["data/quadruped/corpus/train.parquet", "data/quadruped/corpus/test.parquet"],
        "quadruped train:",
    ),
    "pose": (
        ["pipelines/pose.py", "rig=quadruped"],
        ["data/quadruped/poses/train.parquet", "data/quadruped/poses/test.parquet"],
        "posing quadruped train",
    ),
    "fit": (
        ["pipelines/fit.py", "rig=quadruped", "regressor=nn", "sampler=none"],
        [
            "models/quadruped/nn-none-none/nn.npz",
            "models/quadruped/nn-none-none/nn.json",
            "models/quadruped/nn-none-none/placement.json",
        ],
        "network training:",
    ),
}


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO / "pipelines")])
    return env


def _command(stage: str, folder: Path) -> list[str]:
    args = STAGES[stage][0]
    paths = [f"paths.data={folder / 'data'}", f"paths.models={folder / 'models'}"]
    return [sys.executable, str(REPO / args[0]), *args[1:], *paths]


def _run(stage: str, folder: Path) -> None:
    command = _command(stage, folder)
    done = subprocess.run(
        command, cwd=folder, env=_env(), capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]


def _kill_mid_way(command: list[str], folder: Path, line: str) -> None:
    """Run ``command`` and SIGKILL it once its output shows ``line``."""
    process = subprocess.Popen(
        command, cwd=folder, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    seen = bytearray()
    reader = threading.Thread(target=lambda: _drain(process, seen), daemon=True)
    reader.start()
    marker = line.encode()
    try:
        deadline = time.monotonic() + 300
        while marker not in seen:
            assert process.poll() is None, seen.decode(errors="replace")[-3000:]
            assert time.monotonic() < deadline, "the stage never reached the kill point"
            time.sleep(0.01)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    assert process.returncode == -signal.SIGKILL


def _drain(process: subprocess.Popen, seen: bytearray) -> None:
    while chunk := process.stdout.read1(1024):
        seen.extend(chunk)


def _prepare(stage: str, folder: Path, reference: Path) -> None:
    """The stage's inputs: the reference run's outputs of the stages before it."""
    order = list(STAGES)
    for earlier in order[: order.index(stage)]:
        for output in STAGES[earlier][1]:
            target = folder / output
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes((reference / output).read_bytes())


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """Inputs for every stage: one uninterrupted run of the stages before fit."""
    folder = tmp_path_factory.mktemp("inputs")
    for stage in list(STAGES)[:-1]:
        _run(stage, folder)
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("stage", list(STAGES))
def test_kill_9_mid_stage_then_rerun_gives_identical_outputs(stage, reference, tmp_path):
    """Outputs record their input paths, so the uninterrupted run is made in the same folder."""
    _prepare(stage, tmp_path, reference)
    outputs = STAGES[stage][1]
    _run(stage, tmp_path)
    whole = {output: (tmp_path / output).read_bytes() for output in outputs}
    for output in outputs:
        (tmp_path / output).unlink()

    _kill_mid_way(_command(stage, tmp_path), tmp_path, STAGES[stage][2])
    for output in outputs:  # nothing half-written: each output absent or complete
        path = tmp_path / output
        assert not path.exists() or path.read_bytes() == whole[output]
    touched = {(tmp_path / output).parent for output in outputs}

    _run(stage, tmp_path)  # dvc repro re-runs the stage
    for output in outputs:
        assert (tmp_path / output).read_bytes() == whole[output], output
    for folder in touched:  # no temporary file or staging folder is left behind
        assert not [p.name for p in folder.iterdir() if p.name.startswith(".")], folder


# --------------------------------------------------------------------------- rigmap map
WALK = REPO.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"
MAP_ARGS = [
    "rig=biped",
    f"input={WALK}",
    "map.first_frame=240",
    "map.frames=8",
    "map.settings.refine_iterations=1",
    "budget.gpr_points=80",
    "budget.length_scales=3",
    "budget.cv_splits=2",
]
TIMINGS = ("frames_per_second", "seconds")  # summary.json's wall-clock fields differ run to run


@pytest.fixture(scope="module")
def biped_data(tmp_path_factory) -> Path:
    """The biped's train corpus and poses, as the animate and pose stages write them."""
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.rigs import load
    from rigmap.store import Layout

    data = tmp_path_factory.mktemp("biped") / "data"
    layout = Layout(data=data, models=data.parent / "models")
    write_corpora(load("biped"), layout, seed=0, fps=24, variation=1.0)
    pose_corpora(load("biped"), layout, batch_size=512, progress=False)
    return data


def _map_outputs(folder: Path) -> dict[str, bytes]:
    """Every file ``rigmap map`` wrote (its clip folder and its map model), by relative path;
    summary.json without its timings."""
    import json

    files = {}
    for path in sorted((folder / "out").rglob("*")) + sorted((folder / "models").rglob("*")):
        if path.is_file():
            data = path.read_bytes()
            if path.name == "summary.json":
                summary = {k: v for k, v in json.loads(data).items() if k not in TIMINGS}
                data = json.dumps(summary, sort_keys=True).encode()
            files[str(path.relative_to(folder))] = data
    return files


@pytest.mark.slow
def test_kill_9_mid_rigmap_map_then_rerun_gives_identical_outputs(biped_data, tmp_path):
    """Trial: ``rigmap map`` killed with SIGKILL while it fits its map model, then re-run:
    nothing half-written after the kill, and the re-run writes what an uninterrupted run does."""
    import shutil

    shutil.copytree(biped_data, tmp_path / "data")
    paths = [
        f"out={tmp_path / 'out'}",
        f"paths.data={tmp_path / 'data'}",
        f"paths.models={tmp_path / 'models'}",
        "--config-dir",
        str(REPO / "conf"),
    ]
    command = [sys.executable, "-m", "rigmap.cli", "map", *MAP_ARGS, *paths]
    done = subprocess.run(
        command, cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    whole = _map_outputs(tmp_path)
    assert any(name.endswith("gpr.npz") for name in whole) and len(whole) > 8, sorted(whole)
    shutil.rmtree(tmp_path / "out")
    shutil.rmtree(tmp_path / "models")
    _kill_mid_way(command, tmp_path, "fitting on")
    for name, data in _map_outputs(tmp_path).items():  # each file absent or whole
        assert whole.get(name) == data, name
    done = subprocess.run(
        command, cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert _map_outputs(tmp_path) == whole
    hidden = [p for p in (tmp_path / "out").rglob(".*")] + list((tmp_path / "models").rglob(".*"))
    assert not hidden, hidden  # no temporary file or staging folder is left behind
