"""MLflow tracking against a real `mlflow server` (and a local SQLite store).

The server runs on 127.0.0.1 at a free port with a temporary SQLite backend
and artifact folder, in its own process group that the fixture always kills.
A small real evaluation on the biped — a least-squares inverse mapping fitted
on biped poses, timed and scored on two test clips — is logged as a parent
run with child runs and a registered pyfunc model; everything is read back
through ``MlflowClient`` and a fresh Python process.
"""

from __future__ import annotations

import json
import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from least_squares_mapping import LeastSquaresMapping
from rig_poses import random_used_controls
from rigmap.evaluation import (
    ClipResult,
    CountingRig,
    MethodResult,
    control_std,
    ground_truth_error,
    joint_error,
    run_timed,
)
from rigmap.tracking import (
    MappingLoggingError,
    MappingToLog,
    Tracker,
    TrackingKeyError,
    TrackingUnavailableError,
    allow_mapping_class,
    flatten_config,
    joint_columns,
    log_inverse_mapping,
    log_method_run,
    method_metrics,
    resolve_tracking_uri,
    safe_name,
    start_parent_run,
)
from rigmap.tracking.store import local_artifact_root

REPO = Path(__file__).resolve().parents[1]
allow_mapping_class(LeastSquaresMapping)  # the pyfunc loader builds only allow-listed classes
CLIPS = {"jump & play": (12, 21), "tai chi": (8, 22)}  # name: (frames, seed)


# --------------------------------------------------------------------------- fixtures
# `mlflow_server` (one real server for the whole session) comes from conftest.py
def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.fixture(scope="module")
def evaluation(biped):
    """A real (small) evaluation: least squares fitted on biped poses, scored on two clips."""
    used = biped.controls.used_indices
    used_names = [biped.control_names[i] for i in used]
    Y_train = random_used_controls(biped, 1000, seed=20, spread=0.35)
    X_train = biped.evaluate(Y_train).reshape(len(Y_train), -1)
    mapping = LeastSquaresMapping(ridge=1.0).fit(X_train, Y_train[:, used])
    mean_pose = biped.evaluate(biped.expand_used(Y_train[:, used].mean(axis=0, keepdims=True)))
    train_std = control_std(Y_train[:, used])
    kinds = [biped.controls.kinds[i] for i in used]

    rig = CountingRig(biped)

    def retarget(X_target):
        Y_used = mapping.predict(X_target.reshape(len(X_target), -1))
        return Y_used, rig.evaluate(biped.expand_used(Y_used))

    clips, curves, inputs, baseline = [], [], [], []
    for name, (frames, seed) in CLIPS.items():
        Y_true = random_used_controls(biped, frames, seed=seed, spread=0.35)
        X_target = biped.evaluate(Y_true)
        (Y_pred, X_pred), timing = run_timed(retarget, X_target, warmup_frames=1, rig=rig)
        truth = ground_truth_error(Y_pred, Y_true[:, used], train_std, kinds, names=used_names)
        clips.append(
            ClipResult(
                name,
                joint_error(X_pred, X_target).per_frame,
                truth.per_frame,
                total_time_s=timing.seconds,
                rig_evaluations=timing.rig.poses,
                rig_calls=timing.rig.calls,
            )
        )
        curves.append(
            pd.DataFrame(Y_pred, columns=used_names).assign(clip=name, frame=range(frames))
        )
        inputs.append(X_target.reshape(frames, -1))
        baseline.append(joint_error(np.repeat(mean_pose, frames, axis=0), X_target).per_frame)
    result = MethodResult("biped", "least_squares", "none", clips, warmup_frames=1)
    controls = pd.concat(curves, ignore_index=True)[["clip", "frame", *used_names]]
    X_test = pd.DataFrame(np.concatenate(inputs), columns=joint_columns(biped.joint_names))
    return {"mapping": mapping, "result": result, "controls": controls, "X_test": X_test,
            "used_names": used_names,
            "mean_pose_error": np.concatenate(baseline).mean()}  # fmt: skip


def _config(long_value: str) -> dict:
    return {
        "rig": {"name": "biped"},
        "sampler": {"name": "none"},
        "regressor": {"name": "least_squares", "ridge": 1.0, "hidden": [64, 64]},
        "refine": {"name": "none", "tolerance": None},
        "notes": long_value,
    }


# --------------------------------------------------------------------------- the server
@pytest.mark.slow
def test_parent_and_method_runs_on_a_real_server(mlflow_server, evaluation, tmp_path):
    from mlflow import MlflowClient

    result = evaluation["result"]
    # real numbers: the linear map is far better than the mean training pose (~720 cm²), not exact
    assert 0 < result.joint_error < 0.25 * evaluation["mean_pose_error"]
    assert result.rig_evaluations == result.frames == 20
    metrics_file = result.write_json(tmp_path / "metrics" / "biped" / "least_squares-none.json")
    tracker = Tracker.open(mlflow_server)
    long_value = "x" * 7000
    with start_parent_run(tracker, "biped", name="test sweep", config={"seed": 0}) as parent:
        first = log_method_run(
            parent, rig="biped", method="least_squares", sampler="none", kernel=None,
            refine=None, config=_config(long_value), result=result,
            predicted_controls=evaluation["controls"],
            model=MappingToLog(
                evaluation["mapping"], "least_squares",
                input_columns=list(evaluation["X_test"].columns),
                output_columns=evaluation["used_names"],
                input_example=evaluation["X_test"].iloc[:2],
            ),
        )  # fmt: skip
        second = log_method_run(
            parent, rig="biped", method="least_squares", sampler="uniform",
            kernel="multiquadric", refine="computed_jacobian", config=_config("short"),
            result=json.loads(metrics_file.read_text()),
        )  # fmt: skip

    client = MlflowClient(mlflow_server)
    experiment = client.get_experiment_by_name("rigmap-biped")
    assert experiment is not None
    assert experiment.tags["mlflow.experimentKind"] == "custom_model_development"
    assert client.get_run(parent.run_id).info.status == "FINISHED"
    children = client.search_runs(
        [experiment.experiment_id], f"tags.mlflow.parentRunId = '{parent.run_id}'"
    )
    assert {run.info.run_id for run in children} == {first.run_id, second.run_id}

    run = client.get_run(first.run_id)
    assert run.info.status == "FINISHED"
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True)
    expected_commit = commit.stdout.strip() if commit.returncode == 0 else "unknown"
    assert {k: run.data.tags[k] for k in ("rig", "method", "sampler", "kernel", "refine")} == {
        "rig": "biped", "method": "least_squares", "sampler": "none", "kernel": "none",
        "refine": "none",
    }  # fmt: skip
    assert run.data.tags["git_commit"] == expected_commit
    assert client.get_run(second.run_id).data.tags["kernel"] == "multiquadric"

    # metrics equal the metrics JSON, averaged and per clip (clip names made key-safe)
    saved = json.loads(metrics_file.read_text())
    for run_id in (first.run_id, second.run_id):
        logged = client.get_run(run_id).data.metrics
        for metric in ("joint_error", "ground_truth_error", "total_time_s", "fps"):
            assert logged[metric] == saved["average"][metric]
            assert logged[f"{metric}/jump_play"] == saved["clips"]["jump & play"][metric]
            assert logged[f"{metric}/tai_chi"] == saved["clips"]["tai chi"][metric]
        assert logged["rig_evaluations"] == saved["average"]["rig_evaluations"] == 20
        assert logged["frames/jump_play"] == 12

    params = run.data.params
    assert params["rig.name"] == "biped" and params["regressor.ridge"] == "1.0"
    assert params["regressor.hidden"] == "[64, 64]" and params["refine.tolerance"] == "null"
    assert len(params["notes"]) == 6000 and params["notes"].endswith("of 7000 chars]")

    names = {a.path for a in client.list_artifacts(first.run_id)}
    assert names >= {"config.yaml", "metrics.json", "per_frame.csv", "per_frame_error.png",
                     "predicted_controls.parquet"}  # fmt: skip
    curves = pd.read_parquet(
        client.download_artifacts(first.run_id, "predicted_controls.parquet", str(tmp_path))
    )
    pd.testing.assert_frame_equal(curves, evaluation["controls"])
    png = Path(client.download_artifacts(first.run_id, "per_frame_error.png", str(tmp_path)))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    config = client.download_artifacts(first.run_id, "config.yaml", str(tmp_path))
    assert OmegaConf.load(config).regressor.hidden == [64, 64]

    # the registered pyfunc model predicts the same controls in a fresh process
    assert first.model is not None and second.model is None
    assert first.model.registered_name == "rigmap-biped-least_squares"
    version = client.get_model_version("rigmap-biped-least_squares", first.model.version)
    assert version.run_id == first.run_id
    X_test = evaluation["X_test"]
    X_test.iloc[:, ::-1].assign(extra=1.0).to_parquet(tmp_path / "joints.parquet")  # order-free
    script = (
        "import sys, mlflow, pandas as pd\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from least_squares_mapping import LeastSquaresMapping\n"
        "from rigmap.tracking import allow_mapping_class, load_pyfunc_model\n"
        "allow_mapping_class(LeastSquaresMapping)  # the loading process trusts the test's class\n"
        "mlflow.set_tracking_uri(sys.argv[1])\n"
        "model = load_pyfunc_model(sys.argv[2])  # MLmodel checked: no code from the folder\n"
        "model.predict(pd.read_parquet(sys.argv[3])).to_parquet(sys.argv[4])\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    done = subprocess.run(
        [sys.executable, "-c", script, mlflow_server, first.model.registered_uri,
         str(tmp_path / "joints.parquet"), str(tmp_path / "controls.parquet")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    predicted = pd.read_parquet(tmp_path / "controls.parquet")
    assert list(predicted.columns) == evaluation["used_names"]
    expected = evaluation["mapping"].predict(X_test.to_numpy())
    np.testing.assert_allclose(predicted.to_numpy(), expected, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_local_sqlite_store_keeps_artifacts_beside_the_database(tmp_path, evaluation):
    from mlflow import MlflowClient

    uri = f"sqlite:///{tmp_path / 'project' / 'mlruns.db'}"
    tracker = Tracker.open(uri)
    args = {"rig": "biped", "method": "least_squares", "sampler": "none", "kernel": None,
            "refine": None, "config": {"rig": {"name": "biped"}}}  # fmt: skip
    with start_parent_run(tracker, "biped", name="local") as parent:
        child = log_method_run(parent, result=evaluation["result"], **args)
        with pytest.raises(ValueError, match="non-empty pandas DataFrame"):
            log_method_run(parent, result=evaluation["result"], predicted_controls=pd.DataFrame(),
                           run_name="broken", **args)  # fmt: skip
        with pytest.raises(ValueError, match="differs from the parent run's rig 'biped'"):
            log_method_run(parent, result=evaluation["result"], **dict(args, rig="quadruped"))
    client = MlflowClient(uri)
    experiment = client.get_experiment_by_name("rigmap-biped")
    expected_root = tmp_path / "project" / "mlartifacts" / "rigmap-biped"
    assert experiment.artifact_location == expected_root.as_uri()
    stored = {p.name for p in expected_root.rglob("*") if p.is_file()}
    assert {"metrics.json", "per_frame.csv", "per_frame_error.png", "config.yaml"} <= stored
    logged = client.get_run(child.run_id).data.metrics
    assert logged["joint_error"] == evaluation["result"].joint_error
    statuses = {
        r.info.run_name: r.info.status for r in client.search_runs([experiment.experiment_id])
    }
    assert statuses == {"local": "FINISHED", "least_squares-none": "FINISHED", "broken": "FAILED"}


# --------------------------------------------------------------------------- fast checks
def test_unreachable_server_fails_fast_and_names_the_uri():
    uri = f"http://127.0.0.1:{_free_port()}"  # nothing listens there
    started = time.perf_counter()
    with pytest.raises(TrackingUnavailableError, match=re.escape(uri)) as error:
        Tracker.open(uri, probe_timeout_s=2.0)
    assert time.perf_counter() - started < 5  # refused at once, not MLflow's minutes of retries
    assert "/health" in str(error.value) and "sqlite:///" in str(error.value)
    assert "scripts/tracking_server.sh start" in str(error.value)  # how to start the project's


def test_silent_server_fails_after_the_probe_timeout():
    """A port that accepts connections but never answers (a hung server) is not a hang."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(1)  # the kernel accepts the connection; nobody ever replies
        uri = f"http://127.0.0.1:{listener.getsockname()[1]}"
        started = time.perf_counter()
        with pytest.raises(TrackingUnavailableError, match=re.escape(uri)):
            Tracker.open(uri, probe_timeout_s=1.0)
        assert time.perf_counter() - started < 5


def test_tracking_uri_precedence(monkeypatch, tmp_path):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.chdir(tmp_path)  # the project is found from the package, not the working dir
    default = resolve_tracking_uri()
    assert default == f"sqlite:///{REPO / 'mlruns.db'}"
    assert local_artifact_root(default) == REPO / "mlartifacts"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://tracking.example:5000")
    assert resolve_tracking_uri() == "http://tracking.example:5000"
    assert resolve_tracking_uri("http://other:80") == "http://other:80"  # explicit beats env
    assert resolve_tracking_uri("sqlite:///runs.db") == f"sqlite:///{tmp_path / 'runs.db'}"


def test_hydra_tracking_configs(monkeypatch):
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    local = OmegaConf.load(REPO / "conf" / "tracking" / "local.yaml")
    assert local.uri is None and resolve_tracking_uri(local.uri).endswith("/mlruns.db")
    server = OmegaConf.load(REPO / "conf" / "tracking" / "server.yaml")
    assert server.uri == "http://127.0.0.1:5000"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", "http://mlflow.internal:8080")
    assert server.uri == "http://mlflow.internal:8080"
    with pytest.raises(ValueError, match=r"unknown fields \['url'\]"):
        Tracker.from_config({"url": "http://x"})


def test_metric_keys_follow_mlflow_rules(evaluation):
    from mlflow.exceptions import MlflowException
    from mlflow.utils.validation import _validate_metric_name

    assert safe_name("jump & play") == "jump_play" and safe_name("Tai Chi (slow)") == "Tai_Chi_slow"
    metrics = method_metrics(evaluation["result"].to_dict())
    assert metrics["joint_error"] == evaluation["result"].joint_error
    assert metrics["fps/tai_chi"] == evaluation["result"].clips[1].fps
    for key in metrics:
        _validate_metric_name(key)  # MLflow's own check accepts every key we make
    with pytest.raises(MlflowException):
        _validate_metric_name("joint_error/jump & play")  # and would refuse the raw clip name
    summary = {"average": {"joint_error": 1.0}, "clips": {"a b": {}, "a&b": {}}}
    with pytest.raises(TrackingKeyError, match=r"'a b' and 'a&b' both become 'a_b'"):
        method_metrics(summary)
    with pytest.raises(TrackingKeyError, match="no letters or digits"):
        safe_name(" & ")


def test_flatten_config_writes_json_values_and_truncates():
    config = OmegaConf.create(
        {"a": {"b": 1, "c": [1, 2], "d": None, "e": True, "f": "${a.b}"}, "text": "t" * 6500}
    )
    flat = flatten_config(config)
    assert {k: flat[k] for k in ("a.b", "a.c", "a.d", "a.e", "a.f")} == {
        "a.b": "1", "a.c": "[1, 2]", "a.d": "null", "a.e": "true", "a.f": "1",
    }  # fmt: skip
    assert flat["text"] == "t" * 5968 + "...[truncated 532 of 6500 chars]"  # 6000 characters


class ForgetfulMapping(LeastSquaresMapping):
    """Saves everything but the weights' last row (the intercept): loads a different model."""

    def save(self, folder):
        intercept, self.weights_[-1] = self.weights_[-1].copy(), 0.0
        try:
            return super().save(folder)
        finally:
            self.weights_[-1] = intercept


allow_mapping_class(ForgetfulMapping)


def test_mappings_that_cannot_be_logged_are_refused_before_mlflow(evaluation, tmp_path):
    class Local(LeastSquaresMapping):
        pass

    args = {"rig": "biped", "regressor": "x", "input_columns": list(evaluation["X_test"].columns),
            "output_columns": evaluation["used_names"]}  # fmt: skip
    with pytest.raises(MappingLoggingError, match=r"lacks \['save', 'load \(classmethod\)'\]"):
        log_inverse_mapping("unused://", "run", SimpleNamespace(predict=len), **args)
    local = Local.load(evaluation["mapping"].save(tmp_path / "saved"))
    with pytest.raises(MappingLoggingError, match="cannot be imported by another process"):
        log_inverse_mapping("unused://", "run", local, **args)
    narrow = dict(args, output_columns=evaluation["used_names"][:3])
    with pytest.raises(MappingLoggingError, match=r"gives 211 outputs per row, but 3 output"):
        log_inverse_mapping("unused://", "run", evaluation["mapping"], **narrow)
    forgetful = ForgetfulMapping.load(evaluation["mapping"].save(tmp_path / "forgetful"))
    with pytest.raises(MappingLoggingError, match=r"save\(\) then load\(\) predicts differently"):
        log_inverse_mapping("unused://", "run", forgetful, **args)
