"""The method runner (paper §6.1, Table 1): scores, refinement, rig counts, timing rules.

Tiny inverse mappings are fitted on the face (6 landmarks, 49 used controls: cheap)
from a corpus built into a temporary folder; the script baseline runs on the biped.
Every score is checked against an independent computation from the parquet files.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.animation.library import SPLITS, Variation, build_corpus
from rigmap.animation.posing import pose_corpus
from rigmap.evaluation import (
    EvaluationSetupError,
    RefineSettings,
    TestSet,
    evaluation_jobs,
    get_method,
    run_method,
)
from rigmap.evaluation.novelty import Novelty
from rigmap.refine import PredictedJacobian, jacobian
from rigmap.regression import (
    FeedForwardRegressor,
    GaussianKernel,
    GaussianProcessRegressor,
    LearnedJacobian,
    MeanRegressor,
    MultiquadricKernel,
)
from rigmap.regression.features import inverse_features
from rigmap.retarget.script import script_retarget
from rigmap.store import ModelId

FRAMES_PER_CLIP = 8
#: Table 1's rows and the extra rows these tiny models serve (the joint-space rows fit their own)
ROWS = (
    "script",
    "gpr",
    "gpr_learned_jacobian",
    "gpr_computed_jacobian",
    "nn",
    "nn_computed_jacobian",
    "nn_learned_jacobian",
    "nn_autodiff_jacobian",
    "mean",
)
REFINE = RefineSettings(damping=0.1, tolerance=0.0, max_iterations=2)  # no frame stops early


# --------------------------------------------------------------------------- shared builders
def build_rig_data(rig, data_root: Path) -> Path:
    """The animate and pose stages' files for ``rig`` under ``data_root/<rig>/``."""
    folder = data_root / rig.name
    for split in SPLITS:
        corpus = build_corpus(rig, split, seed=0, fps=24, variation=Variation())
        corpus.write(folder / "corpus" / f"{split}.parquet")
        pose_corpus(rig, corpus).write(folder / "poses" / f"{split}.parquet")
    return folder


def training_rows(rig, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """Features and used controls of the train split, straight from the parquet files."""
    poses = pd.read_parquet(folder / "poses" / "train.parquet")
    corpus = pd.read_parquet(folder / "corpus" / "train.parquet")
    positions, cog, rotation = pose_arrays(poses, rig)
    features = inverse_features(positions, cog, rotation, n_joints=rig.n_joints, where="train")
    return features, corpus[rig.used_controls].to_numpy()


def pose_arrays(poses: pd.DataFrame, rig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = len(poses)
    joints = [f"{j}.{a}" for j in rig.joint_names for a in "xyz"]
    positions = poses[joints].to_numpy().reshape(n, rig.n_joints, 3)
    cog = poses[["cog.x", "cog.y", "cog.z"]].to_numpy()
    rotation = poses[[f"cog_rot.{r}{c}" for r in range(3) for c in range(3)]].to_numpy()
    return positions, cog, rotation.reshape(n, 3, 3)


def fit_tiny_models(rig, folder: Path, models_root: Path) -> dict[str, Path]:
    """Tiny GPRs (multiquadric + learned Jacobian, gaussian) and networks, contract layout."""
    X, Y = training_rows(rig, folder)
    names = {"rig_name": rig.name, "control_names": rig.used_controls}
    out = models_root / rig.name
    folders = {}
    for label, kernel in (("multiquadric", MultiquadricKernel()), ("gaussian", GaussianKernel())):
        gpr = GaussianProcessRegressor(
            kernel=kernel, n_points=40, n_length_scales=4, cv_splits=2, seed=0
        ).fit(X, Y, rest_index=0, **names)
        folders[f"gpr-none-{label}"] = gpr.save(out / f"gpr-none-{label}")
        if label == "multiquadric":
            support = gpr.support_indices_
            J = jacobian(rig, rig.expand_used(Y[support]))
            learned = LearnedJacobian(kernel=gpr.kernel_, search_length_scale=False)
            learned.fit(X[support], J, **names).save(out / f"gpr-none-{label}" / "learned_jacobian")
    folders["mean-none-none"] = MeanRegressor().fit(X, Y, **names).save(out / "mean-none-none")
    for seed, sampler in enumerate(("pca_gaussian", "none")):
        network = FeedForwardRegressor(
            hidden=24, epochs=3, batch_size=32, seed=seed, progress=False
        )
        folders[f"nn-{sampler}-none"] = network.fit(X, Y, **names).save(out / f"nn-{sampler}-none")
    return folders


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def face_setup(tmp_path_factory):
    from rigmap.rigs import load

    rig = load("face")
    root = tmp_path_factory.mktemp("face")
    folder = build_rig_data(rig, root / "data")
    fit_tiny_models(rig, folder, root / "models")
    models = root / "models" / "face"
    return {
        "rig": rig,
        "folder": folder,
        "test_set": TestSet.load(rig, folder).first_frames(FRAMES_PER_CLIP),
        "gpr": GaussianProcessRegressor.load(models / "gpr-none-multiquadric", rig=rig),
        "learned": LearnedJacobian.load(
            models / "gpr-none-multiquadric" / "learned_jacobian", rig=rig
        ),
        "nn": FeedForwardRegressor.load(models / "nn-pca_gaussian-none", rig=rig),
        "mean": MeanRegressor.load(models / "mean-none-none", rig=rig),
    }


@pytest.fixture(scope="module")
def face_runs(face_setup):
    """Every face method (no script for the face), run once for the module."""
    s = face_setup
    runs = {}
    for name in ROWS:
        method = get_method(name)  # built from the package's conf/method/<name>.yaml
        if method.guess.kind == "script":
            continue
        runs[name] = run_method(
            s["rig"],
            method,
            s["test_set"],
            regressor=s[method.regressor],
            learned_jacobian=s["learned"] if method.refine == "learned_jacobian" else None,
            refine=REFINE if method.refine != "none" else None,
            sampler="none" if method.regressor == "gpr" else "pca_gaussian",
            warmup_frames=1,
        )
    return runs


# --------------------------------------------------------------------------- scores
def test_scores_equal_an_independent_computation(face_setup, face_runs):
    rig, folder = face_setup["rig"], face_setup["folder"]
    poses = pd.read_parquet(folder / "poses" / "test.parquet")
    truth = pd.read_parquet(folder / "corpus" / "test.parquet")
    train = pd.read_parquet(folder / "corpus" / "train.parquet")[rig.used_controls].to_numpy()
    std = train.std(axis=0)
    scored = std > 1e-9
    used = rig.controls.used_indices
    evaluation = face_runs["gpr"]
    result = evaluation.result
    all_joint, all_truth = [], []
    for clip_result in result.clips:
        rows = (poses["clip"] == clip_result.clip).to_numpy().nonzero()[0][:FRAMES_PER_CLIP]
        positions, cog, rotation = pose_arrays(poses.iloc[rows], rig)
        X = inverse_features(positions, cog, rotation, n_joints=rig.n_joints, where="test")
        Y_used = face_setup["gpr"].predict(X)
        full = np.tile(rig.controls.defaults, (len(rows), 1))  # unused controls: defaults
        full[:, used] = Y_used
        joint = ((rig.evaluate(full) - positions) ** 2).reshape(len(rows), -1).mean(axis=1)
        Y_true = truth.iloc[rows][rig.used_controls].to_numpy()
        normalised = ((Y_used - Y_true)[:, scored] / std[scored]) ** 2
        np.testing.assert_allclose(clip_result.joint_error_per_frame, joint, rtol=1e-9)
        np.testing.assert_allclose(
            clip_result.ground_truth_error_per_frame, normalised.mean(axis=1), rtol=1e-9
        )
        np.testing.assert_array_equal(clip_result.frame_numbers, poses["frame"].iloc[rows])
        assert clip_result.fps == pytest.approx(len(rows) / clip_result.total_time_s)
        curves = evaluation.controls[evaluation.controls["clip"] == clip_result.clip]
        np.testing.assert_allclose(curves[rig.used_controls].to_numpy(), Y_used, atol=1e-12)
        all_joint.append(joint)
        all_truth.append(normalised.mean(axis=1))
    # averages weigh every frame alike (the clips differ in length only when cut shorter)
    assert result.joint_error == pytest.approx(np.concatenate(all_joint).mean(), rel=1e-9)
    assert result.ground_truth_error == pytest.approx(np.concatenate(all_truth).mean(), rel=1e-9)
    assert result.joint_error > 1e-4  # a 40-point GPR is not exact: a real number was measured
    assert list(evaluation.controls.columns) == ["clip", "frame", *rig.used_controls]
    assert result.frames == len(evaluation.controls) == 2 * FRAMES_PER_CLIP
    assert result.to_dict()["timing"]["warmup_frames"] == 1


@pytest.mark.parametrize(
    "refined, guess",
    [
        ("gpr_computed_jacobian", "gpr"),
        ("gpr_learned_jacobian", "gpr"),
        ("nn_computed_jacobian", "nn"),
        ("nn_learned_jacobian", "nn"),
        ("nn_autodiff_jacobian", "nn"),
    ],
)
def test_refinement_lowers_the_joint_error_of_its_initial_guess(face_runs, refined, guess):
    refined_result, guess_result = face_runs[refined].result, face_runs[guess].result
    initial = face_runs[refined].initial_joint_error
    for after, before in zip(refined_result.clips, guess_result.clips, strict=True):
        # refinement starts from the very guess the unrefined method returns
        assert initial[after.clip] == pytest.approx(before.joint_error, rel=1e-9)
        assert after.joint_error < 0.5 * before.joint_error
    extra = refined_result.to_dict()["extra"]
    assert extra["refine_settings"] == {
        "damping": 0.1,
        "tolerance": 0.0,
        "max_iterations": 2,
        "control_scale": "training_std",
        "keep_in_range": True,
        "solver": "cholesky",
        "differences": "central",
        "share_every": 1,
        "jacobian_update": "recompute",
        "sparsity": "dense",
        "threads": 1,
        "traced": False,
    }
    assert extra["initial_joint_error"]["average"] == pytest.approx(guess_result.joint_error)


def test_autodiff_and_finite_difference_refinement_agree(face_runs):
    fd, ad = face_runs["nn_computed_jacobian"].result, face_runs["nn_autodiff_jacobian"].result
    for a, b in zip(fd.clips, ad.clips, strict=True):
        np.testing.assert_allclose(a.joint_error_per_frame, b.joint_error_per_frame, rtol=1e-3)


def test_rig_evaluations_are_counted_for_the_timed_pass(face_setup, face_runs):
    n_used = len(face_setup["rig"].used_controls)
    k = REFINE.max_iterations
    per_frame = {
        "gpr": 0,
        "nn": 0,
        # one scoring evaluation of the guess, then per iteration a step's evaluation plus
        # the Jacobian: 2 per used control (central differences), one autodiff forward, none
        "gpr_computed_jacobian": 1 + k * (2 * n_used + 1),
        "nn_computed_jacobian": 1 + k * (2 * n_used + 1),
        "nn_autodiff_jacobian": 1 + k * 2,
        "gpr_learned_jacobian": 1 + k,
        "nn_learned_jacobian": 1 + k,
    }
    for name, expected in per_frame.items():
        for clip in face_runs[name].result.clips:
            # warm-up frames ran first, but the counts cover the timed pass only
            assert clip.rig_evaluations == expected * clip.frames, name
            assert (clip.rig_calls > 0) == (expected > 0), name


def test_script_on_the_biped_counts_its_read_backs(biped, tmp_path):
    folder = build_rig_data(biped, tmp_path / "data")
    test_set = TestSet.load(biped, folder, clips=["Swing Dance", "Tai Chi"]).first_frames(3)
    evaluation = run_method(biped, "script", test_set, warmup_frames=1)
    result = evaluation.result
    assert [c.clip for c in result.clips] == ["Swing Dance", "Tai Chi"]
    for clip, clip_result in zip(test_set.clips, result.clips, strict=True):
        direct = script_retarget(biped, clip.positions, clip.cog, clip.cog_rotation)
        assert clip_result.rig_evaluations == direct.rig_evaluations > 0
        assert clip_result.rig_calls > 0
        rows = evaluation.controls["clip"] == clip.name
        np.testing.assert_allclose(
            evaluation.controls.loc[rows, biped.used_controls].to_numpy(), direct.Y_used
        )
        X = biped.evaluate(biped.expand_used(direct.Y_used))
        expected = ((X - clip.positions) ** 2).reshape(len(clip), -1).mean(axis=1)
        np.testing.assert_allclose(clip_result.joint_error_per_frame, expected, rtol=1e-9)
    assert result.method == "script" and result.sampler == "none"


# --------------------------------------------------------------------------- pieces
def test_learned_jacobian_source_gives_the_frames_refinement_asks_for(face_setup):
    """Refinement passes the frames' indices; the source predicts from their features."""
    clip = face_setup["test_set"].clips[0]
    rig = face_setup["rig"]
    X = inverse_features(
        clip.positions, clip.cog, clip.cog_rotation, n_joints=rig.n_joints, where="t"
    )
    source = PredictedJacobian(face_setup["learned"], X)
    expected = face_setup["learned"].predict(X)
    frames = np.array([1, 4, 5])
    J, cost = source(rig.default_controls(3), clip.positions[frames], frames)
    np.testing.assert_allclose(J, expected[frames])
    assert cost == 0 and J.shape == (3, 3 * rig.n_joints, len(rig.used_controls))
    with pytest.raises(ValueError, match="pass the frames' indices"):
        source(rig.default_controls(1), clip.positions[:1])


def test_bad_setups_are_refused_with_what_was_expected(face_setup):
    rig, test_set = face_setup["rig"], face_setup["test_set"]
    with pytest.raises(EvaluationSetupError, match="unknown method 'gp'; available"):
        get_method("gp")
    with pytest.raises(EvaluationSetupError, match="needs a fitted gpr inverse mapping"):
        run_method(rig, "gpr", test_set)
    with pytest.raises(EvaluationSetupError, match="does not refine, but refine settings"):
        run_method(rig, "gpr", test_set, regressor=face_setup["gpr"], refine=REFINE)
    with pytest.raises(EvaluationSetupError, match="needs a learned Jacobian"):
        run_method(rig, "nn_learned_jacobian", test_set, regressor=face_setup["nn"], refine=REFINE)
    computed = get_method("gpr_computed_jacobian")
    with pytest.raises(EvaluationSetupError, match=r"refines with 'computed_jacobian'.*'none'"):
        RefineSettings.from_config({"name": "none"}, computed)
    with pytest.raises(EvaluationSetupError, match="uses the finite_difference Jacobian"):
        RefineSettings.from_config(
            {"name": "computed_jacobian", "jacobian": "autodiff", "damping": 0.1,
             "tolerance": 0, "max_iterations": 2}, computed,
        )  # fmt: skip
    with pytest.raises(EvaluationSetupError, match=r"refine\.damping: expected a number >= 0"):
        RefineSettings(damping=-1.0)
    with pytest.raises(EvaluationSetupError, match=r"not found for rig 'face'; its test clips"):
        TestSet.load(rig, face_setup["folder"], clips=["Tai Chi"])
    with pytest.raises(EvaluationSetupError, match="frames per clip: expected an integer >= 1"):
        test_set.first_frames(0)


def test_every_regression_method_reports_its_per_frame_novelty(face_setup, face_runs):
    s = face_setup
    measure = Novelty.from_training(s["test_set"].train_poses, s["rig"].n_joints)
    for name, run in face_runs.items():
        frames = run.result.per_frame_table()
        clip = s["test_set"].clips[0]
        rows = inverse_features(
            clip.positions, clip.cog, clip.cog_rotation, n_joints=s["rig"].n_joints, where="t"
        )
        # these tiny models have no placement: novelty is measured on the pose rows themselves
        expected = measure.distances(rows)
        np.testing.assert_allclose(frames["novelty"].to_numpy()[: len(clip)], expected)
        assert (expected > 0).any(), name  # test frames are not training frames
        confidence = run.result.to_dict()["confidence"]
        assert confidence["per_frame_column"] == "novelty"
        assert -1.0 <= confidence["novelty_error_spearman"] <= 1.0


def test_evaluation_jobs_follow_the_contract_layout(tmp_path):
    methods = evaluation_jobs("methods", "biped", tmp_path, methods=ROWS)
    assert [j.metrics_path.relative_to(tmp_path).as_posix() for j in methods] == [
        "biped/methods/script-none.json",
        "biped/methods/gpr-none.json",
        "biped/methods/gpr_learned_jacobian-none.json",
        "biped/methods/gpr_computed_jacobian-none.json",
        "biped/methods/nn-pca_gaussian.json",
        "biped/methods/nn_computed_jacobian-pca_gaussian.json",
        "biped/methods/nn_learned_jacobian-pca_gaussian.json",
        "biped/methods/nn_autodiff_jacobian-pca_gaussian.json",
        "biped/methods/mean-none.json",
    ]
    folders = {j.method.name: (j.model_id, j.jacobian_model_id) for j in methods}
    assert folders["script"] == (None, None)
    gpr = ModelId("gpr", "none", "multiquadric")
    assert folders["gpr_learned_jacobian"] == (gpr, gpr)
    assert folders["nn_learned_jacobian"] == (ModelId("nn", "pca_gaussian"), gpr)
    assert folders["nn_autodiff_jacobian"] == (ModelId("nn", "pca_gaussian", "none"), None)
    assert str(folders["nn_learned_jacobian"][0]) == "nn-pca_gaussian-none"
    samplers = evaluation_jobs("samplers", "face", tmp_path, samplers=["none", "gmm"])
    assert [(j.metrics_path.name, str(j.model_id)) for j in samplers] == [
        ("nn-none.json", "nn-none-none"),
        ("nn-gmm.json", "nn-gmm-none"),
    ]
    kernels = evaluation_jobs("kernels", "face", tmp_path, kernels=["linear"])
    assert [(j.metrics_path.name, str(j.model_id)) for j in kernels] == [
        ("gpr-linear.json", "gpr-none-linear")
    ]
    with pytest.raises(EvaluationSetupError, match=r"expected one of \('methods', 'samplers'"):
        evaluation_jobs("method", "face", tmp_path)
    with pytest.raises(EvaluationSetupError, match="nothing to run"):
        evaluation_jobs("kernels", "face", tmp_path, kernels=[])
