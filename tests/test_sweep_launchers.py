"""Sweeps: rigmap's Optuna sweeper (killed and resumed, one MLflow parent with a child per
trial on PostgreSQL), resumed through the submitit launcher with submitit's local executor.

Trials are the real ``pipelines/tune.py`` trials of the quadruped's joint-space network,
shrunk to a couple of seconds each.
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


def tune_command(tmp_path: Path, uri: str, *extra: str) -> list[str]:
    return [
        sys.executable, str(REPO / "pipelines" / "tune.py"), "--multirun",
        f"hydra.sweeper.storage=sqlite:///{tmp_path / 'optuna.db'}",
        f"hydra.sweep.dir={tmp_path / 'sweep'}", f"tracking.uri={uri}", *TINY, *extra,
    ]  # fmt: skip


def clean_env() -> dict:
    return {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}


def children(client, parent_id: str):
    from mlflow.entities import ViewType

    parent = client.get_run(parent_id)
    return client.search_runs(
        [parent.info.experiment_id],
        filter_string=f"tags.mlflow.parentRunId = '{parent_id}'",
        run_view_type=ViewType.ACTIVE_ONLY,
    )


def test_optuna_sweep_killed_mid_trial_resumes_through_submitit(pg_tracking_server, tmp_path):
    """Killed (SIGKILL) while trial 1 runs under the basic launcher; the same sweep resumed
    with submitit's local executor, the trial cut off asked again as a submitit job."""
    import optuna
    from mlflow import MlflowClient

    command = tune_command(tmp_path, pg_tracking_server.uri, "hydra.sweeper.n_trials=2",
                           "hydra.sweeper.study_name=killed")  # fmt: skip
    sweep = subprocess.Popen(
        command, cwd=REPO, env=clean_env(), text=True, start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )  # fmt: skip
    seen = []
    for line in sweep.stdout:  # kill once trial 1 is running (trial 0 done and logged)
        seen.append(line)
        if "#1 :" in line:
            os.killpg(sweep.pid, signal.SIGKILL)
            break
    sweep.wait(timeout=60)
    assert sweep.returncode == -signal.SIGKILL, "".join(seen)[-3000:]
    submitit = ["hydra/launcher=submitit_local", "hydra.sweeper.n_jobs=2",
                "hydra.launcher.timeout_min=10"]  # fmt: skip
    resumed = subprocess.run([*command, *submitit], cwd=REPO, env=clean_env(),
                             capture_output=True, text=True, timeout=600)  # fmt: skip
    assert resumed.returncode == 0, resumed.stdout[-3000:] + resumed.stderr[-3000:]
    assert "was cut off by a kill: retried" in resumed.stdout + resumed.stderr

    study = optuna.load_study(study_name="killed", storage=f"sqlite:///{tmp_path / 'optuna.db'}")
    states = [t.state.name for t in study.trials]
    assert states.count("COMPLETE") == 2 and states.count("FAIL") == 1, states
    # the cut-off trial's parameters were tried again
    failed = next(t for t in study.trials if t.state.name == "FAIL")
    assert any(t.params == failed.params for t in study.trials if t.state.name == "COMPLETE")
    client = MlflowClient(pg_tracking_server.uri)
    parent_id = study.user_attrs["mlflow_parent_run_id"]
    parent = client.get_run(parent_id)
    assert parent.info.status == "FINISHED" and parent.data.tags["best_trial"]
    runs = children(client, parent_id)
    assert len(runs) == 2 and {r.info.status for r in runs} == {"FINISHED"}
    assert sorted(float(r.data.metrics["joint_error"]) for r in runs) == sorted(
        t.value for t in study.trials if t.state.name == "COMPLETE"
    )
    assert (tmp_path / "sweep" / "optimization_results.yaml").is_file()
    # the resumed trial ran as a submitit job, with its own log
    job_logs = list((tmp_path / "sweep" / ".submitit").glob("*/*_log.out"))
    assert len(job_logs) == 1 and "trial: joint error" in job_logs[0].read_text()


def test_slurm_launcher_config_and_sweeper_space_compose():
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(str(REPO / "conf"), version_base="1.3"):
        cfg = compose("tune", overrides=["hydra/launcher=slurm"], return_hydra_config=True)
    launcher, sweeper = cfg.hydra.launcher, cfg.hydra.sweeper
    assert launcher._target_.endswith("submitit_launcher.SlurmLauncher")
    assert launcher.cpus_per_task == 2 and launcher.array_parallelism == 32
    assert sweeper._target_.endswith("rigmap_optuna_sweeper.optuna_sweeper.OptunaSweeper")
    searched = {"gaussian_scale", "hidden", "learning_rate", "control_weight"}
    assert set(sweeper.params) == {f"regressor.{name}" for name in searched}
    assert sweeper.n_trials == 12 and cfg.regressor._target_.endswith("JointSpaceNetworkRegressor")


def test_sweeper_refuses_a_bad_search_space():
    from hydra_plugins.rigmap_optuna_sweeper.optuna_sweeper import OptunaSweeper, distribution

    with pytest.raises(ValueError, match="type 'gaussian'; expected float, int or categorical"):
        distribution("regressor.hidden", {"type": "gaussian"})
    with pytest.raises(ValueError, match=r"'regressor\.hidden' needs 'high'"):
        distribution("regressor.hidden", {"type": "int", "low": 1})
    with pytest.raises(ValueError, match="params is empty"):
        OptunaSweeper("s", "sqlite:///x.db", "minimize", 2, 1, 0, {}, "quadruped")


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
    """hydra/launcher=ray_cluster (hydra-ray-launcher): the sweep's two trials run as Ray
    tasks on a head started apart from the sweep, and both complete in the study."""
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
