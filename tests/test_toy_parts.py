"""Adding a part is one class plus one yaml: a toy sampler, regressor and method, end to end.

Each part is written into the test's temporary tree only — a Python module (on
``sys.path``) and a yaml in a config folder added to Hydra's search path, its name
given in the evaluate lists by override — and then runs through the real code paths:
the supersample stage, the fit stage, loading the model folder, the evaluate stage
(and its method runner, :func:`rigmap.evaluation.runner.run_method`) on a few test
frames, scored with the evaluation's metric functions, and the report's Table 1 and
Table 2 builders with the labels :mod:`rigmap.catalog` reads from the toys' classes.
"""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from rigmap.evaluation.methods import TestSet, run_method
from rigmap.evaluation.metrics import ground_truth_error, joint_error
from rigmap.regression import load_regressor
from rigmap.sampling import load_samples
from stage_scripts import load_stage as _stage

ROOT = Path(__file__).resolve().parents[1]
N_SAMPLES = 200
FRAMES = 12  # test frames per clip the runner scores
TINY = [
    "budget.epochs=2",
    "budget.hidden=32",
    "budget.batch_size=64",
    f"budget.samples={N_SAMPLES}",
]

JITTER_MODULE = '''
"""A toy strategy: a random corpus frame moved by uniform noise of ``width`` stds."""

import numpy as np

from rigmap.sampling import Sampler


class JitterSampler(Sampler):
    name = "jitter"
    title = "Uniform Jitter"
    extra = True
    min_corpus_frames = 2

    def __init__(self, width: float = 0.1):
        self.width = width

    def _fit(self, corpus):
        self.corpus_ = corpus.copy()
        self.std_ = corpus.std(axis=0)

    def _sample(self, n, rng):
        frames = rng.integers(0, len(self.corpus_), size=n)
        noise = rng.uniform(-1.0, 1.0, size=(n, self.std_.size)) * (self.width * self.std_)
        return self.corpus_[frames] + noise
'''

RIDGE_MODULE = '''
"""A toy inverse mapping: scikit-learn's ridge regression as a rigmap Regressor."""

from sklearn.linear_model import Ridge

from rigmap.regression import ModelFingerprint, Regressor
from rigmap.regression.validation import check_training_data


class RidgeRegressor(Regressor):
    name = "ridge"
    saved_arrays = ("coef", "intercept")

    def __init__(self, alpha: float = 1.0):
        self.alpha = alpha

    def fit(self, X, Y, *, rig_name=None, control_names=None):
        X, Y = check_training_data(X, Y, "RidgeRegressor")
        ridge = Ridge(alpha=self.alpha).fit(X, Y)
        self.coef_, self.intercept_ = ridge.coef_, ridge.intercept_
        self.fingerprint_ = ModelFingerprint.build(X.shape[1], Y.shape[1], rig_name, control_names)
        return self

    def predict(self, X):
        X, single = self.fingerprint_.check_inputs(X, "RidgeRegressor")
        Y = X @ self.coef_.T + self.intercept_
        return Y[0] if single else Y
'''


ROUND_MODULE = '''
"""A toy refiner: the guess's controls rounded to ``decimals`` places (no rig evaluation)."""

import numpy as np

from rigmap.evaluation.method import Refiner


class RoundedRefinement(Refiner):
    kind = "rounded"
    title = "Rounded"

    def __init__(self, name: str = "rounded", decimals: int = 2):
        super().__init__(name)
        self.decimals = decimals

    def __call__(self, rig, Y_used, positions, features, learned, train_std, settings):
        return np.round(Y_used, self.decimals), None
'''

#: the toy method: the toy regressor's guess, then the toy refiner (one yaml, no defaults)
ROUNDED_METHOD_YAML = """\
_target_: rigmap.evaluation.method.Method
extra: true
guess:
  _target_: rigmap.evaluation.method.RegressorGuess
  regressor: ridge
  title: Ridge
refine:
  _target_: toy_round.RoundedRefinement
  name: rounded
  decimals: 2
"""


@pytest.fixture(scope="module")
def toy_tree(tmp_path_factory):
    """The two toy parts: modules on sys.path and yaml files in an extra config folder."""
    tree = tmp_path_factory.mktemp("toy_parts")
    (tree / "toy_jitter.py").write_text(textwrap.dedent(JITTER_MODULE))
    (tree / "toy_ridge.py").write_text(textwrap.dedent(RIDGE_MODULE))
    (tree / "toy_round.py").write_text(textwrap.dedent(ROUND_MODULE))
    conf = tree / "conf"
    (conf / "sampler").mkdir(parents=True)
    (conf / "regressor").mkdir()
    (conf / "method").mkdir()
    (conf / "method" / "ridge_rounded.yaml").write_text(ROUNDED_METHOD_YAML)
    (conf / "sampler" / "jitter.yaml").write_text(
        "_target_: toy_jitter.JitterSampler\nwidth: 0.2\n"
    )
    (conf / "regressor" / "ridge.yaml").write_text(
        "_target_: toy_ridge.RidgeRegressor\nalpha: 0.5\n"
    )
    sys.path.insert(0, str(tree))
    yield tree
    sys.path.remove(str(tree))
    for module in ("toy_jitter", "toy_ridge", "toy_round"):
        sys.modules.pop(module, None)


def config(toy_tree: Path, data: Path, models: Path, *overrides: str):
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        return compose(
            config_name="config",
            overrides=[
                f"hydra.searchpath=[file://{toy_tree / 'conf'}]",
                "rig=quadruped",
                f"paths.data={data}",
                f"paths.models={models}",
                *TINY,
                *overrides,
            ],
        )


@pytest.fixture(scope="module")
def folders(toy_tree, tmp_path_factory):
    """Quadruped corpus and poses (animate + pose stages) and an empty models folder."""
    data, models = tmp_path_factory.mktemp("toy_data"), tmp_path_factory.mktemp("toy_models")
    cfg = config(toy_tree, data, models)
    _stage("animate").run(cfg)
    _stage("pose").run(cfg, progress=False)
    return data, models


@pytest.fixture(scope="module")
def test_set(folders, quadruped):
    data, _ = folders
    return TestSet.load(quadruped, data / "quadruped").first_frames(FRAMES)


def check_scores(rig, model, test_set, evaluation):
    """The runner's errors are the metric functions applied to the model's predictions."""
    from rigmap.regression.features import inverse_features

    for clip, result in zip(test_set.clips, evaluation.result.clips, strict=True):
        features = inverse_features(
            clip.positions, clip.cog, clip.cog_rotation, n_joints=rig.n_joints, where=clip.name
        )
        predicted = model.predict(features)
        posed = rig.evaluate(rig.expand_used(predicted))
        expected_joint = joint_error(posed, clip.positions).per_frame
        expected_truth = ground_truth_error(
            predicted, clip.controls, test_set.train_std, test_set.control_kinds
        ).per_frame
        np.testing.assert_allclose(result.joint_error_per_frame, expected_joint, rtol=1e-9)
        np.testing.assert_allclose(result.ground_truth_error_per_frame, expected_truth, rtol=1e-9)
    average = evaluation.result.average()
    assert np.isfinite(average["joint_error"]) and average["joint_error"] > 0


def test_a_toy_sampler_runs_through_supersample_fit_and_evaluate(
    toy_tree, folders, quadruped, test_set
):
    data, models = folders
    cfg = config(toy_tree, data, models, "sampler=jitter", "regressor=nn")
    result = _stage("supersample").run(cfg, progress=False)

    # supersample: the toy's samples, clamped to the rig and posed
    assert result.path == data / "quadruped" / "samples" / "jitter.npz"
    samples = load_samples(result.path)
    assert samples["meta"]["sampler"] == "jitter"
    assert samples["meta"]["sampler_params"] == {"width": 0.2}
    assert samples["controls"].shape == (N_SAMPLES, len(quadruped.used_controls))
    assert samples["positions"].shape == (N_SAMPLES, quadruped.n_joints, 3)
    corpus = _train_corpus(data, quadruped)
    reach = 0.2 * corpus.std(axis=0) + 1e-9  # every control within width stds of its frame
    near = (np.abs(samples["controls"][:, None] - corpus[None]) <= reach).all(axis=2)
    assert near.any(axis=1).all()
    posed = quadruped.pose(quadruped.expand_used(samples["controls"][:5]))
    np.testing.assert_allclose(samples["positions"][:5], posed.positions, atol=1e-9)

    # fit: the network on the corpus plus the toy's samples
    fit = _stage("fit").run(cfg)
    assert fit.folder == models / "quadruped" / "nn-jitter-none"
    record = json.loads((fit.folder / "fit.json").read_text())
    assert record["sampler"] == "jitter" and record["rows"]["samples"] == N_SAMPLES
    assert record["inputs"]["samples"] == str(result.path)

    # evaluate: the runner's scores are the metric functions' on the loaded model
    model = load_regressor(fit.folder, rig=quadruped)
    evaluation = run_method(quadruped, "nn", test_set, regressor=model, sampler="jitter")
    assert evaluation.result.sampler == "jitter"
    check_scores(quadruped, model, test_set, evaluation)


def test_a_toy_regressor_is_fitted_saved_loaded_and_evaluated(
    toy_tree, folders, quadruped, test_set
):
    data, models = folders
    cfg = config(toy_tree, data, models, "regressor=ridge", "sampler=none")
    fit = _stage("fit").run(cfg)

    assert fit.folder == models / "quadruped" / "ridge-none-none"
    names = sorted(p.name for p in fit.folder.iterdir())
    assert names == ["fit.json", "placement.json", "ridge.json", "ridge.npz"]
    record = json.loads((fit.folder / "fit.json").read_text())
    assert record["regressor"] == "ridge" and record["kernel"] == "none"
    assert record["model_file"] == "ridge.json" and "learned_jacobian" not in record

    # the fitted coefficients are scikit-learn's ridge on the placement-free training rows
    from sklearn.linear_model import Ridge

    from rigmap.regression.fitting import load_training_data

    training = load_training_data(quadruped, data, "none")
    placement = fit.model.placement
    inputs = placement.inputs(training.features, "check")
    targets = placement.targets(training.controls, training.features, "check")
    reference = Ridge(alpha=0.5).fit(inputs, targets)
    np.testing.assert_allclose(fit.model.regressor.coef_, reference.coef_, rtol=1e-10)

    # saved and loaded: the same predictions, the same class, refusing another rig
    loaded = load_regressor(fit.folder, rig=quadruped)
    assert type(loaded.regressor).__name__ == "RidgeRegressor"
    assert loaded.regressor.get_params() == {"alpha": 0.5}
    np.testing.assert_array_equal(
        loaded.predict(training.features[:50]), fit.model.predict(training.features[:50])
    )
    with pytest.raises(ValueError, match="fitted for rig 'quadruped'"):
        load_regressor(fit.folder, rig="biped")

    # evaluated like the built-in regressors ("nn" is a regressor method; only the label)
    evaluation = run_method(quadruped, "nn", test_set, regressor=loaded)
    check_scores(quadruped, loaded, test_set, evaluation)
    # a linear map is a real mapping: far better than the corpus mean on the training rows
    assert record["training_error"]["ground_truth_error"] < 0.5


def _train_corpus(data: Path, rig) -> np.ndarray:
    from rigmap.animation.corpus import Corpus

    path = data / rig.name / "corpus" / "train.parquet"
    return Corpus.read(path, control_names=rig.used_controls).values()


def _evaluate(toy_tree, data, models, metrics, *overrides):
    cfg = config(
        toy_tree,
        data,
        models,
        f"paths.metrics={metrics}",
        "evaluate.log_to_mlflow=false",
        f"evaluate.frames_per_clip={FRAMES}",
        "evaluate.progress=false",
        *overrides,
    )
    return _stage("evaluate").run(cfg)


def _fitted(toy_tree, data, models, *overrides):
    """The fit stage's model folder for ``overrides`` (fitted here unless already there)."""
    cfg = config(toy_tree, data, models, *overrides)
    if "sampler=jitter" in overrides:
        _stage("supersample").run(cfg, progress=False)
    return _stage("fit").run(cfg).folder


def test_a_toy_method_and_sampler_reach_the_reports_tables(toy_tree, folders, quadruped, test_set):
    from rigmap.catalog import packaged_conf, read_catalogue
    from rigmap.reports import ReportSettings
    from rigmap.reports.metrics_tree import load_metrics
    from rigmap.reports.tables import methods_table, sampling_table

    data, models = folders
    metrics = data.parent / f"{data.name}_metrics"
    ridge = _fitted(toy_tree, data, models, "regressor=ridge", "sampler=none")
    _fitted(toy_tree, data, models, "regressor=nn", "sampler=jitter")
    _fitted(toy_tree, data, models, "regressor=gpr", "sampler=none", "budget.gpr_points=40")
    method = ["+method@method.ridge_rounded=ridge_rounded", "evaluate.methods=[ridge_rounded]"]
    _evaluate(toy_tree, data, models, metrics, "evaluate.set=methods", *method)
    _evaluate(
        toy_tree, data, models, metrics, "evaluate.set=samplers", "evaluate.samplers=[jitter]"
    )
    _evaluate(
        toy_tree, data, models, metrics, "evaluate.set=kernels", "evaluate.kernels=[multiquadric]"
    )

    # evaluate: the toy method's scores are the metric functions' on the rounded ridge guess
    folder = metrics / "quadruped"
    record = json.loads((folder / "methods" / "ridge_rounded-none.json").read_text())
    assert record["extra"]["refine"] == "rounded" and record["extra"]["regressor"] == "ridge"
    model = load_regressor(ridge, rig=quadruped)
    rounded = type("Rounded", (), {"predict": lambda self, X: np.round(model.predict(X), 2)})()
    per_frame = pd.read_csv(folder / "per_frame" / "methods" / "ridge_rounded-none.csv")
    expected = _per_frame_errors(quadruped, rounded, test_set)
    np.testing.assert_allclose(per_frame["joint_error"], expected[0], rtol=1e-9)
    np.testing.assert_allclose(per_frame["ground_truth_error"], expected[1], rtol=1e-9)
    assert json.loads((folder / "samplers" / "nn-jitter.json").read_text())["sampler"] == "jitter"

    # the report: its rows labelled from the toys' classes and yaml, read with the toy folder
    settings = ReportSettings(
        rigs=("quadruped",),
        method_rigs=("quadruped",),
        sampler_rigs=("quadruped",),
        methods=("ridge_rounded",),
        samplers=("jitter",),
        kernels=("multiquadric",),
        nn_sampler="jitter",
        catalogue=read_catalogue([packaged_conf(), toy_tree / "conf"]),
    )
    tree = load_metrics(metrics, data, settings)
    table1, table2 = methods_table(tree, settings), sampling_table(tree, settings)
    assert [row[1] for row in table1.rows] == ["Ridge & Rounded (extra)"] * 4
    average = table1.data[table1.data["motion"] == "Average"].iloc[0]
    assert average["method_label"] == "Ridge & Rounded"
    assert average["joint_error"] == pytest.approx(record["average"]["joint_error"])
    assert [row[0] for row in table2.rows] == ["Uniform Jitter (extra)"]
    assert list(table2.data["sampler_label"]) == ["Uniform Jitter"]
    # a name the catalogue does not know prints as itself (no KeyError)
    plain = ReportSettings(
        rigs=("quadruped",), method_rigs=("quadruped",), methods=("ridge_rounded",)
    )
    assert plain.catalogue.method("ridge_rounded").display == "ridge_rounded"


def _per_frame_errors(rig, model, test_set):
    from rigmap.regression.features import inverse_features

    joint, truth = [], []
    for clip in test_set.clips:
        features = inverse_features(
            clip.positions, clip.cog, clip.cog_rotation, n_joints=rig.n_joints, where=clip.name
        )
        predicted = model.predict(features)
        posed = rig.evaluate(rig.expand_used(predicted))
        joint.append(joint_error(posed, clip.positions).per_frame)
        truth.append(
            ground_truth_error(
                predicted, clip.controls, test_set.train_std, test_set.control_kinds
            ).per_frame
        )
    return np.concatenate(joint), np.concatenate(truth)
