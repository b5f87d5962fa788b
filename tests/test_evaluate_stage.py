"""The evaluate stage: Hydra wiring, metrics files, the CLI, and MLflow runs on a real server.

A face corpus and tiny fitted mappings (see test_methods) live in temporary folders; the
stage reads them through ``paths.*`` overrides exactly as DVC would run it.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from rigmap.app.evaluate import method_catalog
from rigmap.evaluation import EvaluationSetupError, RefineSettings
from rigmap.regression import FeedForwardRegressor, GaussianProcessRegressor
from rigmap.regression.features import feature_names, inverse_features
from test_methods import build_rig_data, fit_tiny_models

ROOT = Path(__file__).resolve().parents[1]
FRAMES = 5


def _stage():
    """pipelines/evaluate.py as a module (the pipelines are scripts, not a package)."""
    sys.path.insert(0, str(ROOT / "pipelines"))
    try:
        spec = importlib.util.spec_from_file_location(
            "evaluate", ROOT / "pipelines" / "evaluate.py"
        )
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(ROOT / "pipelines"))


def _evaluate_group() -> list[str]:
    """``+evaluate=default`` until conf/config.yaml lists the group in its defaults."""
    defaults = yaml.safe_load((ROOT / "conf" / "config.yaml").read_text())["defaults"]
    listed = any(isinstance(d, dict) and "evaluate" in d for d in defaults)
    return [] if listed else ["+evaluate=default"]


@pytest.fixture(scope="module")
def face(tmp_path_factory):
    from rigmap.rigs import load

    rig = load("face")
    root = tmp_path_factory.mktemp("evaluate_face")
    build_rig_data(rig, root / "data")
    fit_tiny_models(rig, root / "data" / "face", root / "models")
    return {"rig": rig, "root": root}


def _overrides(face, *extra: str) -> list[str]:
    root = face["root"]
    return [
        "rig=face",
        *_evaluate_group(),
        f"paths.data={root / 'data'}",
        f"paths.models={root / 'models'}",
        f"paths.metrics={root / 'metrics'}",
        f"evaluate.frames_per_clip={FRAMES}",
        "evaluate.progress=false",
        *extra,
    ]


def _head_commit() -> str:
    done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    return done.stdout.strip() if done.returncode == 0 else "unknown"


def _run_stage(overrides: list[str]) -> list[Path]:
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
        return _stage().run(cfg)


# --------------------------------------------------------------------------- files, no MLflow
def test_the_three_sets_write_their_metrics_files(face):
    metrics = face["root"] / "metrics" / "face"
    off = "evaluate.log_to_mlflow=false"
    _run_stage(_overrides(face, off, "evaluate.set=methods", "evaluate.methods=[gpr,nn]"))
    written = _run_stage(
        _overrides(face, off, "evaluate.set=kernels", "evaluate.kernels=[multiquadric,gaussian]")
    )
    written += _run_stage(
        _overrides(face, off, "evaluate.set=samplers", "evaluate.samplers=[none,pca_gaussian]")
    )
    assert sorted(p.relative_to(metrics).as_posix() for p in written) == [
        "kernels/gpr-gaussian.json", "kernels/gpr-multiquadric.json",
        "per_frame/kernels/gpr-gaussian.csv", "per_frame/kernels/gpr-multiquadric.csv",
        "per_frame/samplers/nn-none.csv", "per_frame/samplers/nn-pca_gaussian.csv",
        "samplers/nn-none.json", "samplers/nn-pca_gaussian.json",
    ]  # fmt: skip
    # the set's folder holds its JSONs alone (DVC reads it as metrics), the CSVs are plots
    assert {p.name for p in (metrics / "methods").iterdir()} == {
        "gpr-none.json", "nn-pca_gaussian.json"
    }  # fmt: skip
    assert {p.name for p in (metrics / "per_frame" / "methods").iterdir()} == {
        "gpr-none.csv", "nn-pca_gaussian.csv"
    }  # fmt: skip

    def read(name):
        return json.loads((metrics / name).read_text())

    gpr = read("methods/gpr-none.json")
    assert gpr["method"] == "gpr" and gpr["sampler"] == "none" and gpr["rig"] == "face"
    assert gpr["timing"]["warmup_frames"] == 1 and gpr["average"]["frames"] == 2 * FRAMES
    assert gpr["extra"]["model_folders"]["regressor"].endswith("face/gpr-none-multiquadric")
    # the same fitted model scored twice gives the same errors (timing differs)
    kernel = read("kernels/gpr-multiquadric.json")
    for key in ("joint_error", "ground_truth_error", "rig_evaluations"):
        assert kernel["average"][key] == gpr["average"][key]
    assert kernel["extra"]["kernel"] == "multiquadric"
    assert (
        read("kernels/gpr-gaussian.json")["average"]["joint_error"] != gpr["average"]["joint_error"]
    )
    network = read("samplers/nn-pca_gaussian.json")
    assert (
        network["average"]["joint_error"]
        == read("methods/nn-pca_gaussian.json")["average"]["joint_error"]
    )
    assert network["sampler"] == "pca_gaussian"
    assert read("samplers/nn-none.json")["extra"]["model_folders"]["regressor"].endswith(
        "face/nn-none-none"
    )
    per_frame = pd.read_csv(metrics / "per_frame" / "methods" / "gpr-none.csv")
    assert list(per_frame.columns) == [
        "clip", "frame", "joint_error", "ground_truth_error", "novelty"
    ]  # fmt: skip
    assert len(per_frame) == 2 * FRAMES
    assert per_frame["joint_error"].mean() == pytest.approx(gpr["average"]["joint_error"])


def test_the_method_group_builds_every_method_of_table_1_once(face):
    overrides = _overrides(
        face, "method.gpr_computed_jacobian.refine.damping=0.3", "budget.refine_iterations=4",
    )  # fmt: skip
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
    config = OmegaConf.to_container(cfg, resolve=True)
    catalog = method_catalog(config["method"])
    yamls = sorted(p.stem for p in (ROOT / "conf" / "method").glob("*.yaml"))
    assert sorted(catalog) == yamls  # every yaml is composed, under its own name
    kinds = {n: (m.guess.kind, m.regressor, m.refine_label) for n, m in catalog.items()}
    assert kinds["script"] == ("script", None, "none")
    assert kinds["gpr_learned_jacobian"] == ("regressor", "gpr", "learned_jacobian")
    assert kinds["nn_computed_jacobian"] == ("regressor", "nn", "finite_difference")
    assert kinds["nn_autodiff_jacobian"] == ("regressor", "nn", "autodiff")
    assert kinds["mean"] == ("regressor", "mean", "none")
    tuned = catalog["nn_joint_space_tuned"]
    assert tuned.regressor == "nn_joint_space" and tuned.tune["steps"] == 160
    computed = catalog["gpr_computed_jacobian"]
    assert computed.refine_settings == RefineSettings(
        damping=0.3,
        tolerance=1e-4,
        max_iterations=4,
        differences="forward",
        sparsity="coloured",
        solver="block_cholesky",
        traced=True,  # the refine config default (a Blender rig ignores it)
    )
    assert catalog["nn_computed_jacobian"].refine_settings.damping == "auto"  # its node only
    learned = catalog["nn_learned_jacobian"]
    assert learned.needs_learned_jacobian and learned.refine_settings.max_iterations == 4
    assert catalog["gpr"].refine_settings is None and not catalog["gpr"].needs_learned_jacobian
    # the report's labels are the built methods' own (rigmap.catalog reads the same yamls)
    from rigmap.catalog import read_catalogue

    rows = read_catalogue([ROOT / "conf"]).methods
    assert [(r.key, r.label, r.extra) for r in rows] == [
        (n, catalog[n].title, catalog[n].extra) for n in cfg.evaluate.methods
    ]
    assert catalog["nn_joint_space_computed_jacobian"].title == (
        "Joint-space NN & Computed Jacobian"
    )
    node = config["method"]["gpr_computed_jacobian"]
    negative = {**node, "refine": {**node["refine"], "damping": -1}}
    expected = r"method\.gpr_computed_jacobian .*refine\.damping: expected a number >= 0"
    with pytest.raises(EvaluationSetupError, match=expected):
        method_catalog({"gpr_computed_jacobian": negative})


def test_a_method_is_one_yaml(face, tmp_path):
    """A toy method (its yaml in a copy of conf/) runs through the stage with no code change."""
    import shutil

    conf = tmp_path / "conf"
    shutil.copytree(ROOT / "conf", conf)
    (conf / "method" / "gpr_damped.yaml").write_text(
        "defaults:\n  - /refine@refine: computed_jacobian\n  - _self_\n"
        "_target_: rigmap.evaluation.method.Method\n"
        "guess:\n  _target_: rigmap.evaluation.method.RegressorGuess\n  regressor: gpr\n"
        "refine:\n  damping: 0.5\n"
    )
    defaults = conf / "evaluate" / "default.yaml"
    defaults.write_text(
        defaults.read_text().replace(
            "  - _self_", "  - /method@_global_.method.gpr_damped: gpr_damped\n  - _self_", 1
        )
    )
    overrides = _overrides(
        face, "evaluate.log_to_mlflow=false", "evaluate.methods=[gpr,gpr_damped]",
        f"paths.metrics={tmp_path / 'metrics'}",
    )  # fmt: skip
    with initialize_config_dir(config_dir=str(conf), version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
        _stage().run(cfg)
    folder = tmp_path / "metrics" / "face" / "methods"
    plain = json.loads((folder / "gpr-none.json").read_text())
    tight = json.loads((folder / "gpr_damped-none.json").read_text())
    assert tight["method"] == "gpr_damped" and tight["extra"]["refine_settings"]["damping"] == 0.5
    assert tight["extra"]["jacobian"] == "finite_difference"
    assert tight["average"]["joint_error"] <= plain["average"]["joint_error"]
    assert tight["average"]["rig_evaluations"] > 0 == plain["average"]["rig_evaluations"]


def test_the_cli_runs_the_stage_in_process(face, tmp_path, capsys):
    from rigmap import cli

    out = tmp_path / "metrics"
    overrides = [o for o in _overrides(face) if not o.startswith("paths.metrics")]
    code = cli.main(
        ["evaluate", *overrides, f"paths.metrics={out}", "evaluate.log_to_mlflow=false",
         "evaluate.set=kernels", "evaluate.kernels=[gaussian]"]
    )  # fmt: skip
    assert code == 0
    result = json.loads((out / "face" / "kernels" / "gpr-gaussian.json").read_text())
    assert result["method"] == "gpr" and result["extra"]["kernel"] == "gaussian"
    assert result["extra"]["experiment"] == "quick"  # the experiment group's choice, recorded
    assert result["extra"]["budget"]["gpr_points"] == 250
    assert "gpr-gaussian" in capsys.readouterr().out  # the summary table


def test_missing_model_folders_are_named_before_any_work(face, tmp_path):
    overrides = _overrides(
        face, "evaluate.log_to_mlflow=false", "evaluate.set=kernels",
        "evaluate.kernels=[multiquadric,linear]", f"paths.metrics={tmp_path}",
    )  # fmt: skip
    with pytest.raises(FileNotFoundError, match=r"gpr-none-linear \(for gpr\).*fit stage") as error:
        _run_stage(overrides)
    assert not any(tmp_path.rglob("*.json"))  # nothing ran, not even the kernel that exists
    # the message gives the command that writes the missing folder (there is no `fit` stage)
    root = face["root"]
    command = (f"`python pipelines/fit.py rig=face regressor=gpr sampler=none kernel=linear "
               f"paths.data={root / 'data'} paths.models={root / 'models'}`")  # fmt: skip
    assert command in str(error.value)
    assert "dvc repro fit`" not in str(error.value)


@pytest.mark.slow
def test_cli_runs_the_stage(face, tmp_path):
    out = tmp_path / "metrics"
    overrides = [o for o in _overrides(face) if not o.startswith("paths.metrics")]
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    done = subprocess.run(
        [sys.executable, "-m", "rigmap.cli", "evaluate", *overrides, f"paths.metrics={out}",
         "evaluate.log_to_mlflow=false", "evaluate.methods=[nn]"],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads((out / "face" / "methods" / "nn-pca_gaussian.json").read_text())
    assert result["method"] == "nn" and result["average"]["frames"] == 2 * FRAMES
    assert "nn-pca_gaussian" in done.stdout  # the summary table


# --------------------------------------------------------------------------- MLflow
@pytest.mark.slow
def test_runs_on_a_real_server_match_the_metrics_files(face, mlflow_server, tmp_path):
    import mlflow
    from mlflow import MlflowClient

    methods = ["gpr", "gpr_learned_jacobian", "nn", "nn_autodiff_jacobian"]
    metrics = tmp_path / "metrics"
    overrides = _overrides(
        face, f"paths.metrics={metrics}", f"tracking.uri={mlflow_server}",
        f"evaluate.methods=[{','.join(methods)}]",
    )  # fmt: skip
    commits = {_head_commit()}
    _run_stage(overrides)
    commits.add(_head_commit())  # the checkout may get a commit while the stage runs

    client = MlflowClient(mlflow_server)
    experiment = client.get_experiment_by_name("rigmap-face")
    runs = client.search_runs([experiment.experiment_id])
    parents = [r for r in runs if r.data.tags.get("kind") == "sweep"]
    assert len(parents) == 1 and parents[0].info.status == "FINISHED"
    assert parents[0].data.tags["evaluation_set"] == "methods"
    children = {
        r.data.tags["method"]: r
        for r in runs
        if r.data.tags.get("mlflow.parentRunId") == parents[0].info.run_id
    }
    assert sorted(children) == sorted(methods)
    expected_tags = {
        "gpr": ("none", "multiquadric", "none"),
        "gpr_learned_jacobian": ("none", "multiquadric", "learned_jacobian"),
        "nn": ("pca_gaussian", "none", "none"),
        "nn_autodiff_jacobian": ("pca_gaussian", "none", "computed_jacobian"),
    }
    for method, run in children.items():
        tags = run.data.tags
        assert (tags["sampler"], tags["kernel"], tags["refine"]) == expected_tags[method]
        assert tags["rig"] == "face" and tags["git_commit"] in commits
        assert run.info.status == "FINISHED"
        saved = json.loads(
            (metrics / "face" / "methods" / f"{method}-{tags['sampler']}.json").read_text()
        )
        logged = run.data.metrics
        for metric, value in saved["average"].items():
            assert logged[metric] == value, (method, metric)
        for clip, values in saved["clips"].items():
            for metric, value in values.items():
                assert logged[f"{metric}/{clip.replace(' ', '_')}"] == value, (method, clip)
        params = run.data.params
        assert params["rig.name"] == "face" and params["evaluate.frames_per_clip"] == str(FRAMES)
        artifacts = {a.path for a in client.list_artifacts(run.info.run_id)}
        assert {"config.yaml", "metrics.json", "per_frame.csv", "per_frame_error.png",
                "predicted_controls.parquet"} <= artifacts  # fmt: skip
    assert children["nn_autodiff_jacobian"].data.tags["jacobian"] == "autodiff"
    assert children["gpr"].data.params["method.regressor"] == "gpr"  # the method's own config
    assert children["gpr_learned_jacobian"].data.params["refine.name"] == "learned_jacobian"
    assert children["gpr"].data.params["kernel.name"] == "multiquadric"
    curves = pd.read_parquet(
        client.download_artifacts(
            children["nn"].info.run_id, "predicted_controls.parquet", str(tmp_path)
        )
    )
    assert list(curves.columns[:2]) == ["clip", "frame"] and len(curves) == 2 * FRAMES

    # each regressor is registered once; the registered model predicts the in-process controls
    rig = face["rig"]
    models = face["root"] / "models" / "face"
    from rigmap.evaluation import TestSet

    clip = TestSet.load(rig, face["root"] / "data" / "face").clips[0]
    X = inverse_features(clip.positions, clip.cog, clip.cog_rotation, n_joints=rig.n_joints,
                         where="test")  # fmt: skip
    inputs = pd.DataFrame(X, columns=feature_names(list(rig.joint_names)))
    loaded_in_process = {
        "gpr": GaussianProcessRegressor.load(models / "gpr-none-multiquadric", rig=rig),
        "nn": FeedForwardRegressor.load(models / "nn-pca_gaussian-none", rig=rig),
    }
    previous = mlflow.get_tracking_uri()
    mlflow.set_tracking_uri(mlflow_server)
    try:
        for regressor, in_process in loaded_in_process.items():
            versions = client.search_model_versions(f"name = 'rigmap-face-{regressor}'")
            assert len(versions) == 1
            assert versions[0].run_id == children[regressor].info.run_id
            model = mlflow.pyfunc.load_model(
                f"models:/rigmap-face-{regressor}/{versions[0].version}"
            )
            predicted = model.predict(inputs.iloc[:, ::-1])  # columns are matched by name
            assert list(predicted.columns) == list(rig.used_controls)
            np.testing.assert_allclose(predicted.to_numpy(), in_process.predict(X), atol=1e-9)
    finally:
        mlflow.set_tracking_uri(previous)
