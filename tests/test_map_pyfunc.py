"""The map pyfunc model: saved, loaded by MLflow and served over REST, it maps like map_clip."""

from __future__ import annotations

import dataclasses
import json
import time

import mlflow
import numpy as np
import pandas as pd
import pytest

from rigmap.map.clip import MapSettings, map_clip
from rigmap.map.joint_map import MappedTargets
from rigmap.map.partial import JointSubset, SubsetMapping
from rigmap.tracking.map_model import (
    MapModelInputError,
    MapModelParts,
    input_frame,
    save_map_model,
)
from rigmap.tracking.pyfunc_model import UntrustedModelError
from test_map_partial import EFFECTORS, gpr, random_poses

# plain Eq. 13 on an unsmoothed 6-frame clip (no pull toward the guess, no smoothing), so one
# iteration visibly refines: what the pyfunc model must reproduce is map_clip, whatever its
# settings
SETTINGS = MapSettings(
    refine_iterations=1, feet=("foot_l", "foot_r"), key_tolerance_cm=0.5, prior_weight=0.0,
    smoothing_frames=0.0,
)  # fmt: skip
FRAMES = 6


@pytest.fixture(scope="module")
def fitted(biped, tmp_path_factory):
    """A GPR on 120 poses of the biped's effectors, a smooth 6-frame clip, the saved model."""
    Y, X, _ = random_poses(biped, 120, seed=0)
    subset = JointSubset.from_mapping(EFFECTORS, name="effectors", rig=biped)
    mapping = SubsetMapping.fit(biped, subset, X, Y, gpr(120))
    std, hold = Y.std(axis=0), np.median(Y, axis=0)
    ends, _, _ = random_poses(biped, 2, seed=5)
    blend = np.linspace(0.0, 1.0, FRAMES)[:, None]
    pose = biped.pose(biped.expand_used((1 - blend) * ends[0] + blend * ends[1]))
    world = (np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :])[
        :, subset.columns(biped)
    ]
    request = input_frame(world, subset.joints)
    parts = MapModelParts(
        biped,
        mapping,
        SETTINGS,
        control_std=std,
        hold_values=hold,
        fps=24.0,
        input_example=request.iloc[:1],
    )
    folder = save_map_model(tmp_path_factory.mktemp("map-model") / "model", parts)
    targets = MappedTargets("biped", subset.joints, world, 24.0, "test clip", 1.0, (), ())
    expected = map_clip(biped, targets, mapping, SETTINGS, control_std=std, hold_values=hold)
    return {"folder": folder, "mapping": mapping, "targets": targets, "std": std, "hold": hold,
            "request": request, "expected": expected}  # fmt: skip


@pytest.fixture(scope="module")
def loaded(fitted):
    return mlflow.pyfunc.load_model(str(fitted["folder"]))


def test_loaded_model_maps_like_map_clip(biped, fitted, loaded):
    request, expected = fitted["request"], fitted["expected"]
    shuffled = request.iloc[:, ::-1].assign(frame=np.arange(FRAMES))  # order-free, extras ignored
    controls = loaded.predict(shuffled)
    assert list(controls.columns) == biped.control_names and len(controls) == FRAMES
    np.testing.assert_allclose(controls.to_numpy(), expected.controls, rtol=0, atol=1e-12)
    unused = np.setdiff1d(np.arange(biped.n_controls), biped.controls.used_indices)
    defaults = np.tile(biped.controls.defaults[unused], (FRAMES, 1))
    np.testing.assert_array_equal(controls.to_numpy()[:, unused], defaults)
    # refinement is part of the model: without it (a request parameter) the joints are further off
    guess = map_clip(biped, fitted["targets"], fitted["mapping"],
                     dataclasses.replace(SETTINGS, refine_iterations=0),
                     control_std=fitted["std"], hold_values=fitted["hold"])  # fmt: skip
    unrefined = loaded.predict(request, params={"refine_iterations": 0})
    np.testing.assert_allclose(unrefined.to_numpy(), guess.controls, rtol=0, atol=1e-12)
    assert expected.frame_error_cm.mean() < 0.5 * guess.frame_error_cm.mean()


def test_the_model_folder_says_what_it_maps(biped, fitted, loaded):
    spec = json.loads((fitted["folder"] / "data" / "map_model" / "map_model.json").read_text())
    assert spec["rig"] == "biped" and spec["subset"] == "effectors" and spec["fps"] == 24.0
    assert spec["settings"]["refine_iterations"] == 1
    assert spec["settings"]["feet"] == ["foot_l", "foot_r"]
    np.testing.assert_array_equal(spec["control_std"], fitted["std"])
    schema = loaded.metadata.get_input_schema().input_names()
    assert schema == list(fitted["request"].columns) and len(schema) == 3 * len(EFFECTORS["joints"])
    assert loaded.metadata.get_output_schema().input_names() == biped.control_names
    params = {p.name: p.default for p in loaded.metadata.get_params_schema().params}
    assert params == {"fps": 24.0, "refine_iterations": 1}
    saved = sorted(p.name for p in fitted["folder"].parent.iterdir())
    assert saved == ["model"]  # written atomically: no staging folder left beside it


def test_bad_requests_get_clear_errors(fitted, loaded):
    request = fitted["request"]
    with pytest.raises(mlflow.exceptions.MlflowException, match=r"missing inputs \['head.y'\]"):
        loaded.predict(request.drop(columns=["head.y"]))
    nan = request.copy()
    nan.loc[3, "hand_l.z"] = np.nan
    with pytest.raises(MapModelInputError, match="joint 'hand_l' z is nan at frame 3"):
        loaded.predict(nan)
    with pytest.raises(MapModelInputError, match=r"the clip is empty \(0 frames\)"):
        loaded.predict(request.iloc[:0])
    with pytest.raises(MapModelInputError, match="refine_iterations -1 must be an integer >= 0"):
        loaded.predict(request, params={"refine_iterations": -1})
    with pytest.raises(MapModelInputError, match=r"fps is -24\.0, expected a positive number"):
        loaded.predict(request, params={"fps": -24.0})
    inner = loaded.unwrap_python_model()  # without MLflow's schema check, the model's own
    with pytest.raises(MapModelInputError, match=r"lacks 2 of the 21 joint columns .*'head.y'"):
        inner.predict(None, request.drop(columns=["head.y", "foot_r.x"]))


def test_a_tampered_model_is_refused(fitted, tmp_path):
    import shutil

    copy = shutil.copytree(fitted["folder"], tmp_path / "model")
    spec_file = copy / "data" / "map_model" / "map_model.json"
    spec = json.loads(spec_file.read_text())
    spec_file.write_text(json.dumps({**spec, "rig": "quadruped"}))
    with pytest.raises(UntrustedModelError, match="saved for rig 'quadruped' with 211 used"):
        mlflow.pyfunc.load_model(str(copy))
    spec_file.write_text(json.dumps({**spec, "rig": {"name": "biped", "path": "/tmp/x.py"}}))
    with pytest.raises(UntrustedModelError, match="rig must be a registered rig name"):
        mlflow.pyfunc.load_model(str(copy))
    spec_file.write_text(json.dumps(spec))
    outside = shutil.copytree(
        copy / "data" / "map_model" / "subset_mapping", tmp_path / "elsewhere"
    )
    shutil.rmtree(copy / "data" / "map_model" / "subset_mapping")
    (copy / "data" / "map_model" / "subset_mapping").symlink_to(outside)
    with pytest.raises(UntrustedModelError, match="outside the model folder"):
        mlflow.pyfunc.load_model(str(copy))


def test_export_takes_std_and_held_values_from_the_train_corpus(biped, fitted, tmp_path):
    from rigmap.animation.library import build_corpus
    from rigmap.error_measures import control_std
    from rigmap.store import Layout
    from rigmap.tracking.map_model import export_map_model

    layout = Layout(data=tmp_path / "data")
    corpus = build_corpus(biped, "train", seed=0)
    corpus.write(layout.corpus("biped", "train"))
    fitted["mapping"].save(tmp_path / "effectors")
    folder = export_map_model(tmp_path / "exported", rig_name="biped", layout=layout,
                              mapping_folder=tmp_path / "effectors", settings=SETTINGS)  # fmt: skip
    spec = json.loads((folder / "data" / "map_model" / "map_model.json").read_text())
    np.testing.assert_array_equal(spec["control_std"], control_std(corpus.values()))
    np.testing.assert_array_equal(spec["hold_values"], np.median(corpus.values(), axis=0))
    assert spec["fps"] == 30.0 and spec["settings"]["key_tolerance_cm"] == 0.5
    model = mlflow.pyfunc.load_model(str(folder))
    assert model.metadata.get_input_schema().input_names() == list(fitted["request"].columns)


@pytest.mark.slow
def test_logged_model_is_registered_and_loads_by_name(biped, fitted, tmp_path):
    from rigmap.tracking.map_model import log_map_model

    mlflow.set_tracking_uri(f"sqlite:///{tmp_path / 'mlruns.db'}")
    try:
        # an experiment id of our own, not mlflow.set_experiment: that sets a process-wide
        # active experiment and MLFLOW_EXPERIMENT_ID, which later tests' runs would inherit
        experiment = mlflow.create_experiment("rigmap-biped")
        with mlflow.start_run(experiment_id=experiment):
            parts = MapModelParts(
                biped,
                fitted["mapping"],
                SETTINGS,
                control_std=fitted["std"],
                hold_values=fitted["hold"],
                fps=24.0,
            )
            info = log_map_model(parts, registered_model_name="rigmap-biped-map-effectors")
        assert info.registered_model_version == 1
        model = mlflow.pyfunc.load_model("models:/rigmap-biped-map-effectors/1")
        params = {p.name: p.default for p in model.metadata.get_params_schema().params}
        assert params == {"fps": 24.0, "refine_iterations": 1}
        assert model.metadata.run_id == info.run_id
        assert model.metadata.get_output_schema().input_names() == biped.control_names
    finally:
        mlflow.set_tracking_uri(None)


# --------------------------------------------------------------------------- mlflow models serve
@pytest.mark.slow
def test_served_model_answers_over_rest(fitted, loaded):
    from rigmap.tracking.model_server import post_json, served_model

    request = fitted["request"]
    split = {"columns": list(request.columns), "data": request.to_numpy().tolist()}
    with served_model(fitted["folder"]) as url:
        started = time.perf_counter()
        status, answer = post_json(f"{url}/invocations", {"dataframe_split": split})
        served_s = time.perf_counter() - started
        assert status == 200, answer
        served = pd.DataFrame(answer["predictions"])
        # JSON carries every float's shortest repr, so the server sees the very same targets
        assert list(served.columns) == loaded.metadata.get_output_schema().input_names()
        difference = np.abs(served.to_numpy() - fitted["expected"].controls).max()
        assert difference <= 1e-9
        print(f"served map of {len(request)} frames in {served_s:.2f} s, differs by {difference}")

        missing = {"columns": split["columns"][:7] + split["columns"][8:],
                   "data": [row[:7] + row[8:] for row in split["data"]]}  # fmt: skip
        status, answer = post_json(f"{url}/invocations", {"dataframe_split": missing})
        assert status == 400 and "missing inputs ['head.y']" in answer["message"]
        nan = {"columns": split["columns"], "data": [list(row) for row in split["data"]]}
        nan["data"][3][split["columns"].index("hand_l.z")] = None
        status, answer = post_json(f"{url}/invocations", {"dataframe_split": nan})
        assert status == 400 and "joint 'hand_l' z is nan at frame 3" in answer["message"]
