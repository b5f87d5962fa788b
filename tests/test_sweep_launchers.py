"""Sweeps with the maintained Optuna sweeper (hydra-optuna-sweeper) and rigmap's callback
(rigmap.app.optuna_sweep): a 12-trial study killed and resumed, its trials resumed as
submitit jobs, one MLflow parent run with a child per trial; and a sweep on a Ray head.

Trials are the real ``pipelines/tune.py`` trials of the quadruped's joint-space network,
shrunk to a few seconds each.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TINY = [
    "regressor.n_gaussian=100",
    "regressor.n_wide=20",
    "regressor.pretrain_epochs=1",
    "tune.train_rows=60",
    "tune.val_rows=20",
]
MAINTAINED = "hydra_plugins.hydra_optuna_sweeper.optuna_sweeper.OptunaSweeper"


def tune_command(tmp_path: Path, uri: str, *extra: str) -> list[str]:
    return [
        sys.executable, str(REPO / "pipelines" / "tune.py"), "--multirun",
        f"hydra.sweeper.storage=sqlite:///{tmp_path / 'optuna.db'}",
        f"hydra.sweep.dir={tmp_path / 'sweep'}", f"tracking.uri={uri}", *TINY, *extra,
    ]  # fmt: skip


def clean_env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    return {**env, "PYTHONUNBUFFERED": "1"}


def children(client, parent_id: str):
    from mlflow.entities import ViewType

    parent = client.get_run(parent_id)
    return client.search_runs(
        [parent.info.experiment_id],
        filter_string=f"tags.mlflow.parentRunId = '{parent_id}'",
        run_view_type=ViewType.ACTIVE_ONLY,
    )


def load_study(tmp_path: Path, name: str):
    import optuna

    return optuna.load_study(study_name=name, storage=f"sqlite:///{tmp_path / 'optuna.db'}")


def states(study) -> list[str]:
    return [t.state.name for t in study.trials]


def kill_at_launch(command: list[str], job: int) -> str:
    """Run the sweep and SIGKILL its process group once job ``job`` is launched (the jobs
    before it complete, it is cut off while it runs); the output seen so far."""
    sweep = subprocess.Popen(
        command, cwd=REPO, env=clean_env(), text=True, start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )  # fmt: skip
    seen = []
    for line in sweep.stdout:
        seen.append(line)
        if f"#{job} :" in line:
            os.killpg(sweep.pid, signal.SIGKILL)
            break
    sweep.wait(timeout=60)
    out = "".join(seen)
    assert sweep.returncode == -signal.SIGKILL, out[-3000:]
    return out


def run_sweep(command: list[str]) -> str:
    done = subprocess.run(
        command, cwd=REPO, env=clean_env(), capture_output=True, text=True, timeout=900
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, out[-3000:]
    return out


def check_mlflow(tmp_path: Path, uri: str, study) -> None:
    """One FINISHED parent run, one FINISHED child per complete trial, named after it."""
    from mlflow import MlflowClient
    from omegaconf import OmegaConf

    complete = [t for t in study.trials if t.state.name == "COMPLETE"]
    client = MlflowClient(uri)
    parent_id = study.user_attrs["mlflow_parent_run_id"]
    parent = client.get_run(parent_id)
    assert parent.info.status == "FINISHED"
    assert parent.data.tags["best_trial"] == str(study.best_trial.number)
    runs = children(client, parent_id)
    assert len(runs) == 12 and {r.info.status for r in runs} == {"FINISHED"}
    by_trial = {int(r.data.tags["optuna_trial"]): r for r in runs}
    assert sorted(by_trial) == sorted(t.number for t in complete)
    for trial in complete:
        assert by_trial[trial.number].data.metrics["joint_error"] == trial.value
        assert by_trial[trial.number].info.run_name == f"trial-{trial.number}"
    results = OmegaConf.load(tmp_path / "sweep" / "optimization_results.yaml")
    assert results.best_params == study.best_params and results.best_value == study.best_value
    assert results.best_trial == study.best_trial.number
    assert results.mlflow_parent_run_id == parent_id


def test_optuna_sweep_of_12_killed_and_resumed_ends_with_12_complete_trials(tmp_path):
    """SIGKILL while trial 4 runs under the basic launcher; the same sweep resumed with
    submitit's local executor (two jobs at a time, in other processes) fails the cut-off
    trial, asks its point again and runs the 8 trials missing; a third call runs none."""
    uri = f"sqlite:///{tmp_path / 'mlruns.db'}"
    command = tune_command(tmp_path, uri, "hydra.sweeper.n_trials=12",
                           "hydra.sweeper.study_name=killed")  # fmt: skip
    kill_at_launch(command, 4)
    assert states(load_study(tmp_path, "killed")) == ["COMPLETE"] * 4 + ["RUNNING"]

    submitit = ["hydra/launcher=submitit_local", "hydra.sweeper.n_jobs=2",
                "hydra.launcher.timeout_min=10"]  # fmt: skip
    out = run_sweep([*command, *submitit])
    assert "trial 4 was cut off by a kill: failed, asked again" in out
    assert "4 of 12 trials complete; running the rest" in out
    study = load_study(tmp_path, "killed")
    assert states(study).count("COMPLETE") == 12 and states(study).count("FAIL") == 1
    assert study.trials[4].state.name == "FAIL"
    assert study.trials[5].params == study.trials[4].params  # the cut-off point, asked again
    # the resumed seeded sampler draws new points, not the first run's again
    points = [tuple(t.params.values()) for t in study.trials if t.state.name == "COMPLETE"]
    assert len(set(points)) == 12
    job_logs = list((tmp_path / "sweep" / ".submitit").glob("*/*_log.out"))
    assert len(job_logs) == 8 and all("trial: joint error" in p.read_text() for p in job_logs)
    check_mlflow(tmp_path, uri, study)

    out = run_sweep(command)  # a finished study: nothing more to run
    assert "12 of 12 trials complete" in out and "Launching" not in out
    study = load_study(tmp_path, "killed")
    assert len(study.trials) == 13
    check_mlflow(tmp_path, uri, study)


def test_the_sweeper_is_the_maintained_plugin_on_optuna_4_or_newer():
    import importlib.metadata
    import importlib.util

    import optuna
    from hydra.core.plugins import Plugins
    from hydra.plugins.sweeper import Sweeper

    assert importlib.metadata.version("hydra-optuna-sweeper") == "1.3.0"
    assert int(optuna.__version__.split(".")[0]) >= 4, optuna.__version__
    assert importlib.util.find_spec("hydra_plugins.hydra_optuna_sweeper") is not None
    assert importlib.util.find_spec("hydra_plugins.rigmap_optuna_sweeper") is None
    sweepers = {f"{p.__module__}.{p.__name__}" for p in Plugins.instance().discover(Sweeper)}
    assert MAINTAINED in sweepers and not any("rigmap" in s for s in sweepers), sweepers


def test_slurm_launcher_config_and_sweeper_space_compose():
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        cfg = compose("tune", overrides=["hydra/launcher=slurm"], return_hydra_config=True)
    launcher, sweeper = cfg.hydra.launcher, cfg.hydra.sweeper
    assert launcher._target_.endswith("submitit_launcher.SlurmLauncher")
    assert launcher.cpus_per_task == 2 and launcher.array_parallelism == 32
    assert sweeper._target_ == MAINTAINED
    assert sweeper.sampler._target_ == "optuna.samplers.TPESampler" and sweeper.sampler.seed == 0
    assert sweeper.storage == "sqlite:///outputs/tune/optuna.db"
    assert sweeper.study_name == "quadruped-nn" and sweeper.n_trials == 12
    assert sweeper.params["regressor.hidden"] == "choice(32, 64, 128)"
    assert sweeper.params["regressor.learning_rate"] == "tag(log, interval(1.0e-4, 1.0e-2))"
    searched = {"gaussian_scale", "hidden", "learning_rate", "control_weight"}
    assert set(sweeper.params) == {f"regressor.{name}" for name in searched}
    callback = cfg.hydra.callbacks.optuna_mlflow
    assert callback._target_ == "rigmap.app.optuna_sweep.OptunaSweepCallback"
    assert callback.rig == "quadruped" and callback.resume is True
    assert cfg.regressor._target_.endswith("JointSpaceNetworkRegressor")


def test_the_sweep_callback_refuses_a_sweep_without_storage_or_a_bad_resume(tmp_path):
    from hydra import compose, initialize_config_dir

    from rigmap.app.optuna_sweep import OptunaSweepCallback

    overrides = ["hydra.sweeper.storage=null", f"tracking.uri=sqlite:///{tmp_path / 'm.db'}"]
    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        cfg = compose("tune", overrides=overrides, return_hydra_config=True)
    with pytest.raises(ValueError, match=r"^hydra\.sweeper\.storage: a resumable Optuna sweep"):
        OptunaSweepCallback("quadruped").on_multirun_start(cfg)
    with pytest.raises(ValueError, match=r"optuna_mlflow\.resume: 'yes' is not true/false"):
        OptunaSweepCallback("quadruped", resume="yes")
    assert not list(tmp_path.iterdir())  # nothing written before the refusal


@pytest.fixture
def loopback_ray_head(tmp_path):
    """``ray start --head --block`` on a free loopback port in its own temporary folder, its
    process group killed at the end (``ray stop`` would also stop other tests' heads)."""
    import socket
    import tempfile
    import time

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    # loopback only: Ray's node address is 127.0.0.1 instead of the machine's network address
    env = {**clean_env(), "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_AUTH_MODE": "token"}
    env["RAY_ADDRESS"] = f"127.0.0.1:{port}"
    temp = tempfile.mkdtemp(prefix="rayh-", dir="/tmp")  # Ray's socket paths must stay short
    ray_bin = Path(sys.executable).with_name("ray")
    head = subprocess.Popen(
        [
            str(ray_bin),
            "start",
            "--head",
            "--block",
            f"--port={port}",
            "--num-cpus=2",
            "--include-dashboard=false",
            "--disable-usage-stats",
            f"--temp-dir={temp}",
        ],
        env={k: v for k, v in env.items() if k != "RAY_ADDRESS"},
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            with socket.socket() as sock:
                if sock.connect_ex(("127.0.0.1", port)) == 0:
                    break
            assert head.poll() is None, "ray start --head exited"
            time.sleep(0.5)
        else:
            pytest.fail("the Ray head did not listen within 120 s")
        yield env
    finally:
        os.killpg(head.pid, signal.SIGTERM)
        try:
            head.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(head.pid, signal.SIGKILL)
        import shutil

        shutil.rmtree(temp, ignore_errors=True)


def test_optuna_sweep_runs_its_trials_as_tasks_on_a_local_ray_head(loopback_ray_head, tmp_path):
    """hydra/launcher=ray_cluster (hydra-ray-launcher) under the maintained Optuna sweeper:
    the sweep's two trials run as Ray tasks on a head started apart from the sweep, and both
    complete in the study."""
    import optuna

    uri = f"sqlite:///{tmp_path / 'mlruns.db'}"
    command = tune_command(
        tmp_path,
        uri,
        "hydra.sweeper.n_trials=2",
        "hydra.sweeper.n_jobs=2",
        "hydra.sweeper.study_name=ray",
        "hydra/launcher=ray_cluster",
    )
    done = subprocess.run(
        command, cwd=REPO, env=loopback_ray_head, capture_output=True, text=True, timeout=600
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, out[-3000:]
    assert "Ray Launcher is launching 2 jobs" in out
    assert (
        f"Connecting to existing Ray cluster at address: {loopback_ray_head['RAY_ADDRESS']}" in out
    )
    # the trials printed from Ray worker processes (Ray prefixes a task's output with its pid)
    assert out.count("(_run_job pid=") >= 2 and out.count("trial: joint error") == 2, out[-3000:]
    study = optuna.load_study(study_name="ray", storage=f"sqlite:///{tmp_path / 'optuna.db'}")
    assert [t.state.name for t in study.trials] == ["COMPLETE", "COMPLETE"]
