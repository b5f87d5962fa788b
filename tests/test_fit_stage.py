"""The ``fit`` stage and ``rigmap fit``: training rows, model folders, learned Jacobian, errors.

One biped corpus (animate + pose stages) and one small pca_gaussian samples file are built
per session in a temporary data folder; fits use tiny budgets.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import hydra
import numpy as np
import pytest
from hydra import compose, initialize_config_dir

from rigmap.animation.corpus import Corpus
from rigmap.cli import main as rigmap_main
from rigmap.evaluation.methods import TestSet, get_method, run_method
from rigmap.evaluation.sample_sweep import fitted_model, joint_space_sweep
from rigmap.refine import jacobian
from rigmap.regression import (
    FeedForwardRegressor,
    GaussianProcessRegressor,
    ModelMismatchError,
    load_learned_jacobian,
    load_regressor,
)
from rigmap.regression.fitting import load_training_data
from rigmap.regression.mapping import InverseMapping
from rigmap.sampling import make_sampler, supersample
from rigmap.store import Layout
from rigmap.store import write_folder_atomic as write_model_folder
from stage_scripts import load_stage as _stage

ROOT = Path(__file__).resolve().parents[1]
N_SAMPLES = 300
TINY = [
    "budget.gpr_points=40",
    "budget.length_scales=3",
    "budget.cv_splits=2",
    "budget.epochs=1",
    "budget.hidden=32",
    "budget.batch_size=64",
    f"budget.samples={N_SAMPLES}",
]


def config(*overrides: str):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory, biped) -> Path:
    """Biped train/test corpus and poses, plus a small pca_gaussian samples file."""
    data = tmp_path_factory.mktemp("fit_data")
    cfg = config("rig=biped", f"paths.data={data}")
    _stage("animate").run(cfg)
    _stage("pose").run(cfg, progress=False)
    corpus = Corpus.read(data / "biped/corpus/train.parquet", control_names=biped.used_controls)
    sampler = make_sampler("pca_gaussian").fit(corpus.values())
    supersample(
        biped, sampler, N_SAMPLES, data / "biped/samples/pca_gaussian.npz", seed=0, progress=False
    )
    return data


@pytest.fixture(scope="module")
def models_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fit_models")


def fit_config(data_dir: Path, models_dir: Path, *overrides: str):
    return config(
        "rig=biped", f"paths.data={data_dir}", f"paths.models={models_dir}", *TINY, *overrides
    )


@pytest.fixture(scope="module")
def gpr_fit(data_dir, models_dir):
    cfg = fit_config(data_dir, models_dir, "regressor=gpr", "sampler=none", "kernel=multiquadric")
    return _stage("fit").run(cfg)


@pytest.fixture(scope="module")
def nn_fit(data_dir, models_dir):
    # a few epochs so the tiny network is clearly better than the mean, not by luck
    cfg = fit_config(
        data_dir, models_dir, "regressor=nn", "sampler=pca_gaussian", "budget.epochs=4"
    )
    return _stage("fit").run(cfg)


def standardised_error(model, data) -> tuple[float, float]:
    """Mean squared control error on the corpus rows in training-std units, and the mean's."""
    rows = slice(0, data.corpus_rows)
    truth = data.controls[rows]
    std = truth.std(axis=0)
    moving = std > 1e-9
    predicted = model.predict(data.features[rows])
    model_error = float((((predicted - truth)[:, moving] / std[moving]) ** 2).mean())
    mean_error = float((((truth.mean(axis=0) - truth)[:, moving] / std[moving]) ** 2).mean())
    return model_error, mean_error


def test_training_rows_add_the_default_pose_when_the_corpus_lacks_it(data_dir, biped):
    data = load_training_data(biped, data_dir, "pca_gaussian")
    corpus = Corpus.read(data_dir / "biped/corpus/train.parquet", control_names=biped.used_controls)
    n = len(corpus.table)
    defaults = biped.controls.defaults[biped.controls.used_indices]
    # no biped corpus frame is the rest pose, so it is appended right after the corpus
    assert not (np.abs(corpus.values() - defaults).max(axis=1) < 1e-9).any()
    assert data.rest_pose_added and data.rest_index == n == data.corpus_rows
    np.testing.assert_array_equal(data.controls[n], defaults)
    rest = biped.pose(biped.default_controls(1))
    np.testing.assert_allclose(data.features[n, : 3 * biped.n_joints], rest.positions.ravel())
    assert (data.rows, data.sample_rows) == (n + 1 + N_SAMPLES, N_SAMPLES)
    assert data.features.shape[1] == 3 * biped.n_joints + 12
    none = load_training_data(biped, data_dir, "none")
    assert none.rows == n + 1 and none.sources["samples"] is None


def test_gpr_folder_holds_model_fit_json_and_learned_jacobian(gpr_fit, data_dir, biped):
    folder = gpr_fit.folder
    assert folder.name == "gpr-none-multiquadric" and folder.parent.name == "biped"
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["fit.json", "gpr.json", "gpr.npz", "learned_jacobian", "placement.json"]
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".")]  # no staging left
    record = json.loads((folder / "fit.json").read_text())
    n_corpus = len(Corpus.read(data_dir / "biped/corpus/train.parquet").table)
    assert (record["rig"], record["regressor"], record["sampler"], record["kernel"]) == (
        "biped",
        "gpr",
        "none",
        "multiquadric",
    )
    assert record["rows"] == {
        "total": n_corpus + 1,
        "corpus": n_corpus,
        "rest_pose_added": 1,
        "samples": 0,
        "sha256": load_training_data(biped, data_dir, "none").digest(),
    }
    assert record["features"]["width"] == 3 * biped.n_joints + 12
    # the biped's root channels were found on the rig and are solved, not regressed
    placement = record["placement"]
    assert [c["name"] for c in placement["ground"]] == ["root.tx", "root.tz"]
    assert placement["turn"]["name"] == "root.ry"
    assert all(abs(c["gain"] - 1.0) < 1e-6 for c in [*placement["ground"], placement["turn"]])
    assert record["features"]["joint_names"] == list(biped.joint_names)
    assert record["outputs"]["controls"] == list(biped.used_controls)
    assert record["seconds"]["total"] >= record["seconds"]["model"] > 0
    assert record["config"]["regressor"]["n_points"] == 40  # the resolved config
    assert record["gpr"]["support_points"] == 40
    search = record["gpr"]["length_scale_search"]
    assert record["gpr"]["length_scale"] in search["candidates"] and len(search["cv_errors"]) == 3

    model = load_regressor(folder, rig=biped)
    assert isinstance(model, InverseMapping)
    assert isinstance(model.regressor, GaussianProcessRegressor)
    # subsampling started from the rest pose, the row the stage added
    assert model.support_indices_[0] == record["rest_pose"]["index"] == n_corpus
    data = load_training_data(biped, data_dir, "none")
    model_error, mean_error = standardised_error(model, data)
    assert model_error < 0.7 * mean_error
    assert record["training_error"]["ground_truth_error"] == pytest.approx(model_error, rel=1e-6)


def test_learned_jacobian_matches_finite_differences_at_a_support_pose(gpr_fit, data_dir, biped):
    model = load_regressor(gpr_fit.folder, rig=biped)
    learned = load_learned_jacobian(gpr_fit.folder / "learned_jacobian", rig=biped)
    data = load_training_data(biped, data_dir, "none")
    row = int(model.support_indices_[7])
    predicted = learned.predict(data.features[row])
    expected = jacobian(biped, biped.expand_used(data.controls[row : row + 1]))[0]
    assert predicted.shape == expected.shape == (3 * biped.n_joints, len(biped.used_controls))
    relative = np.linalg.norm(predicted - expected) / np.linalg.norm(expected)
    assert relative < 1e-3
    # away from the support the learned Jacobian is an estimate, not a copy of a support one
    assert not np.allclose(learned.predict(data.features[row + 1]), predicted)


def test_network_fits_corpus_plus_samples(nn_fit, data_dir, biped):
    folder = nn_fit.folder
    assert folder.name == "nn-pca_gaussian-none"
    assert sorted(p.name for p in folder.iterdir()) == [
        "fit.json",
        "nn.json",
        "nn.npz",
        "placement.json",
    ]
    record = json.loads((folder / "fit.json").read_text())
    assert (record["regressor"], record["sampler"], record["kernel"]) == (
        "nn",
        "pca_gaussian",
        "none",
    )
    assert record["rows"]["samples"] == N_SAMPLES
    assert record["inputs"]["samples"].endswith("biped/samples/pca_gaussian.npz")
    assert len(record["network"]["loss_history"]) == 4  # budget.epochs
    model = load_regressor(folder, rig=biped)
    assert isinstance(model.regressor, FeedForwardRegressor) and model.hidden == 32
    model_error, mean_error = standardised_error(
        model, load_training_data(biped, data_dir, "pca_gaussian")
    )
    assert model_error < 0.9 * mean_error
    assert record["training_error"]["ground_truth_error"] == pytest.approx(model_error, rel=1e-6)


def test_model_folder_of_another_rig_is_refused(gpr_fit, nn_fit, quadruped):
    with pytest.raises(ModelMismatchError, match=r"fitted for rig 'biped'.*'quadruped'"):
        load_regressor(gpr_fit.folder, rig=quadruped)
    with pytest.raises(ModelMismatchError, match=r"fitted for rig 'biped'.*'quadruped'"):
        load_regressor(nn_fit.folder, rig="quadruped")
    with pytest.raises(ModelMismatchError, match="'biped'"):
        load_learned_jacobian(gpr_fit.folder / "learned_jacobian", rig=quadruped)


def test_missing_inputs_are_named(tmp_path, data_dir):
    partial = tmp_path / "data"
    (partial / "biped/corpus").mkdir(parents=True)
    source = data_dir / "biped/corpus/train.parquet"
    (partial / "biped/corpus/train.parquet").write_bytes(source.read_bytes())
    fit = _stage("fit")
    cfg = fit_config(partial, tmp_path / "models", "regressor=gpr", "sampler=none")
    with pytest.raises(FileNotFoundError, match=r"biped/poses/train\.parquet.*pose stage"):
        fit.run(cfg)
    cfg = fit_config(data_dir, tmp_path / "models", "regressor=nn", "sampler=uniform")
    with pytest.raises(FileNotFoundError, match=r"biped/samples/uniform\.npz"):
        fit.run(cfg)
    assert not (tmp_path / "models").exists()


def test_model_folder_is_replaced_only_when_complete(tmp_path):
    folder = tmp_path / "models" / "rig" / "gpr-none-linear"

    def fill(text):
        def write(staging: Path) -> None:
            (staging / "fit.json").write_text(text)

        return write

    write_model_folder(folder, fill("first"))

    def broken(staging: Path) -> None:
        (staging / "half.json").write_text("{")
        raise RuntimeError("killed mid-fit")

    with pytest.raises(RuntimeError, match="killed mid-fit"):
        write_model_folder(folder, broken)
    assert sorted(p.name for p in folder.parent.iterdir()) == ["gpr-none-linear"]
    assert (folder / "fit.json").read_text() == "first"

    # a folder abandoned by a killed process (its pid is gone) is cleared by the next fit
    finished = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        check=True,
        capture_output=True,
        text=True,
    )
    dead_pid = int(finished.stdout)
    abandoned = folder.parent / f".gpr-none-linear.{dead_pid}.abc123.tmp"
    abandoned.mkdir()
    write_model_folder(folder, fill("second"))
    assert sorted(p.name for p in folder.parent.iterdir()) == ["gpr-none-linear"]
    assert (folder / "fit.json").read_text() == "second"


def test_rigmap_fit_cli(tmp_path, data_dir, capsys, biped):
    models = tmp_path / "models"
    common = [f"paths.data={data_dir}", f"paths.models={models}", *TINY]
    status = rigmap_main(
        ["fit", "rig=biped", "regressor=gpr", "kernel=gaussian", "sampler=none", *common]
    )
    assert status == 0
    folder = models / "biped" / "gpr-none-gaussian"
    assert str(folder) in capsys.readouterr().out
    record = json.loads((folder / "fit.json").read_text())
    assert (record["kernel"], record["gpr"]["support_points"]) == ("gaussian", 40)
    assert not (folder / "learned_jacobian").exists()  # only the multiquadric GPR has one
    assert load_regressor(folder, rig=biped).kernel_.name == "gaussian"

    assert rigmap_main(["fit", "rig=biped", "kernel=nope", *common]) == 2
    assert "Could not find 'kernel/nope'" in capsys.readouterr().err
    missing = tmp_path / "no_data"
    assert rigmap_main(["fit", "rig=biped", "sampler=none", f"paths.data={missing}"]) == 2
    assert f"{missing}/biped/corpus/train.parquet" in capsys.readouterr().err
    assert rigmap_main(["fit", "--config-dir", str(tmp_path), "rig=biped"]) == 2
    assert f"{tmp_path}/config.yaml" in capsys.readouterr().err


# --------------------------------------------------------------------------- samples sweep
def test_sample_sweep_scores_the_network_per_sample_count(data_dir, nn_fit, biped, tmp_path):
    sweep = _stage("sample_sweep")
    cfg = fit_config(
        data_dir, tmp_path / "models", "regressor=nn", "sampler=pca_gaussian", "budget.epochs=4",
        f"paths.metrics={tmp_path / 'metrics'}", "+sweep.fractions=[0.25,1.0]",
    )  # fmt: skip
    written = sweep.run(cfg)
    quarter = round(N_SAMPLES / 4)
    assert [p.name for p in written] == [
        f"nn-pca_gaussian-{quarter}.json",
        f"nn-pca_gaussian-{N_SAMPLES}.json",
    ]
    folder = tmp_path / "metrics" / "biped" / "sample_sweep"
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in written)
    results = {p.name: json.loads(p.read_text()) for p in written}
    full = results[f"nn-pca_gaussian-{N_SAMPLES}.json"]
    assert full["extra"]["samples"] == N_SAMPLES
    assert full["extra"]["training_rows"] == nn_fit.record["rows"]["total"]
    # all the samples: the same seeded fit as the fit stage's network, so the same scores
    test_set = TestSet.load(biped, data_dir / "biped")
    staged = run_method(biped, "nn", test_set, regressor=load_regressor(nn_fit.folder, rig=biped))
    assert full["average"]["joint_error"] == pytest.approx(
        staged.result.average()["joint_error"], rel=1e-9
    )
    quarter_result = results[f"nn-pca_gaussian-{quarter}.json"]
    assert quarter_result["extra"]["training_rows"] == full["extra"]["training_rows"] - (
        N_SAMPLES - quarter
    )
    for result in results.values():
        assert np.isfinite(result["average"]["joint_error"]) and result["average"]["frames"] > 0


JOINT_SPACE_TINY = [
    "regressor=nn_joint_space", "sampler=none", "regressor.n_gaussian=40", "regressor.n_wide=20",
    "regressor.n_local=30", "regressor.pretrain_epochs=1", "regressor.epochs=1",
    "regressor.batch_size=32", "regressor.progress=false", "regressor.hidden=32",
]  # fmt: skip


def test_joint_space_sweep_scales_the_networks_own_draws(data_dir, biped, tmp_path):
    sweep = _stage("sample_sweep")
    cfg = fit_config(
        data_dir, tmp_path / "models", *JOINT_SPACE_TINY,
        f"paths.metrics={tmp_path / 'metrics'}", "+sweep.fractions=[0.5,1.0]",
    )  # fmt: skip
    written = sweep.run(cfg)
    assert [p.name for p in written] == [
        "nn_joint_space-draws-45.json",
        "nn_joint_space-draws-90.json",
    ]
    folder = tmp_path / "metrics" / "biped" / "sample_sweep_joint_space"
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in written)
    results = [json.loads(p.read_text()) for p in written]
    draws = [tuple(r["extra"][k] for k in ("n_gaussian", "n_local", "n_wide")) for r in results]
    assert draws == [(20, 15, 10), (40, 30, 20)]
    # all the draws: the same seeded fit as the fit stage's, so the same scores
    fitted = _stage("fit").run(cfg)
    record = json.loads((fitted.folder / "fit.json").read_text())["joint_space_network"]
    assert set(record["seconds"]) == {"draws_and_setup", "control_space", "joint_space"}
    assert all(seconds > 0 for seconds in record["seconds"].values())
    assert "seconds" not in json.loads((fitted.folder / "nn_joint_space.json").read_text())
    test_set = TestSet.load(biped, data_dir / "biped")
    method = get_method("nn_joint_space")
    staged = run_method(biped, method, test_set, regressor=load_regressor(fitted.folder, rig=biped))
    assert results[1]["average"]["joint_error"] == pytest.approx(
        staged.result.average()["joint_error"], rel=1e-9
    )
    assert results[0]["average"]["joint_error"] != results[1]["average"]["joint_error"]


def test_joint_space_sweep_scores_the_fit_stages_model_when_it_is_the_same_fit(
    data_dir, biped, tmp_path, capsys
):
    cfg = fit_config(
        data_dir, tmp_path / "models", *JOINT_SPACE_TINY,
        f"paths.metrics={tmp_path / 'metrics'}", "+sweep.fractions=[0.5,1.0]",
    )  # fmt: skip
    _stage("fit").run(cfg)
    capsys.readouterr()
    reused = _stage("sample_sweep").run(cfg)
    log = capsys.readouterr().out
    assert log.count("scoring the fit stage's model") == 1 and "+ 90 draws: scoring" in log
    layout = Layout(data=data_dir, models=tmp_path / "models", metrics=tmp_path / "refit")
    make = lambda: hydra.utils.instantiate(cfg.regressor, _convert_="all")  # noqa: E731
    refitted = joint_space_sweep(biped, layout, make, fractions=[0.5, 1.0], reuse_fit=False)
    for a, b in zip(reused, refitted, strict=True):
        scores = [json.loads(p.read_text())["average"] for p in (a, b)]
        for key in ("joint_error", "ground_truth_error"):
            assert scores[0][key] == scores[1][key]
    # another network, or other training rows: the saved model is not that fit
    data = load_training_data(biped, data_dir, "none")
    folder = tmp_path / "models" / "biped" / "nn_joint_space-none-none"
    assert fitted_model(folder, make(), biped, data) is not None
    assert fitted_model(folder, make().set_params(epochs=2), biped, data) is None
    data.controls[0, 0] += 1e-9
    assert fitted_model(folder, make(), biped, data) is None
    (folder / "fit.json").write_text("{")
    with pytest.raises(ValueError, match=r"fit\.json: not valid JSON"):
        fitted_model(folder, make(), biped, data)


def test_joint_space_sweep_refuses_another_regressor_or_no_draws(data_dir, tmp_path):
    sweep = _stage("sample_sweep")
    layout = Layout(data=data_dir, metrics=tmp_path)
    with pytest.raises(ValueError, match="expected regressor=nn_joint_space, got 'nn'"):
        joint_space_sweep(None, layout, lambda: FeedForwardRegressor())
    empty = fit_config(data_dir, tmp_path / "models", *JOINT_SPACE_TINY, "regressor.n_gaussian=0",
                       "regressor.n_local=0", "regressor.n_wide=0",
                       f"paths.metrics={tmp_path}")  # fmt: skip
    with pytest.raises(ValueError, match="draws no poses"):
        sweep.run(empty)


def test_sample_sweep_refuses_counts_it_cannot_draw():
    sweep = _stage("sample_sweep")
    assert sweep.sample_counts([0.5, 0.5, 1.0], 100, 100) == [50, 100]
    with pytest.raises(ValueError, match=r"expected numbers in \(0, 1\]"):
        sweep.sample_counts([0.0], 100, 100)
    with pytest.raises(ValueError, match=r"holds 40 \(budget.samples = 100\)"):
        sweep.sample_counts([1.0], 100, 40)


def test_joint_space_sweep_takes_the_experiments_own_fractions_unless_given():
    """experiment=quick sweeps the joint-space draws at its 3 points, paper at all five;
    sweep.fractions on the command line wins for both sweeps."""
    sweep = _stage("sample_sweep")
    conf = str(ROOT / "conf")
    with initialize_config_dir(version_base=None, config_dir=conf):
        quick = compose("config", overrides=["regressor=nn_joint_space"])
        paper = compose("config", overrides=["regressor=nn_joint_space", "experiment=paper"])
        given = compose("config", overrides=["+sweep.fractions=[0.5,1.0]"])
    assert sweep.is_joint_space(quick) and not sweep.is_joint_space(given)
    assert sweep.sweep_fractions(quick, joint_space=True) == [0.125, 0.5, 1.0]
    assert sweep.sweep_fractions(quick, joint_space=False) == [0.0625, 0.125, 0.25, 0.5, 1.0]
    assert sweep.sweep_fractions(paper, joint_space=True) == [0.0625, 0.125, 0.25, 0.5, 1.0]
    assert sweep.sweep_fractions(given, joint_space=True) == [0.5, 1.0]
