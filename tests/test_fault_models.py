"""No code runs from a model file (issues 35 item 8, 36 item 1): latent, edits, regression
and MLflow models are arrays + JSON, loaded through the same functions the stages use.

Each trial plants what an attacker with write access to the DVC remote or the registry
would: a pickle whose ``__reduce__`` touches a marker file, a payload path out of the
model folder, code in a pyfunc folder. Each asserts a one-line error naming the file and
that the marker was not created. :func:`test_the_planted_pickle_runs_when_unpickled`
shows the payload does create its file when unpickled, so its absence means something.
"""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import pickle
import shutil
import sys

import numpy as np
import pytest
import yaml

from rigmap.regression import GaussianProcessRegressor, ModelFileError, load_regressor
from rigmap.store import Layout


class _Touch:
    """Unpickling this calls ``Path(marker).touch()``: the planted code."""

    def __init__(self, marker: pathlib.Path):
        self.marker = marker

    def __reduce__(self):
        return (pathlib.Path.touch, (pathlib.Path(self.marker),))


def _plant(payload: pathlib.Path, data: bytes) -> None:
    """Write ``data`` as ``payload`` and re-sign its JSON (an attacker edits both files)."""
    payload.write_bytes(data)
    meta_path = payload.with_suffix(".json")
    meta = json.loads(meta_path.read_text())
    meta["payload_sha256"] = hashlib.sha256(data).hexdigest()
    meta_path.write_text(json.dumps(meta))


def _one_line(error: pytest.ExceptionInfo, *names: str) -> None:
    message = str(error.value)
    assert "\n" not in message and all(name in message for name in names), message


def test_the_planted_pickle_runs_when_unpickled(tmp_path):
    marker = tmp_path / "ran"
    pickle.loads(pickle.dumps(_Touch(marker)))
    assert marker.exists()


# --------------------------------------------------------------------------- latent
@pytest.fixture(scope="module")
def latent(tmp_path_factory):
    """A tiny real fit and match of two face labels, saved by the stages' own writer."""
    from rigmap.latent import files
    from rigmap.latent.gplvm import GPLVMSettings
    from rigmap.latent.library import fit_models, rig_sets
    from rigmap.latent.transitions import match_models
    from rigmap.rigs import load

    rig = load("face")
    sets = rig_sets(rig, labels=["happy", "neutral"])
    settings = GPLVMSettings(latent_dim=2, max_iter=10)  # test-sized (ours)
    fitted = fit_models(rig, sets, settings=settings, n_pca=3)
    table = match_models(rig, fitted.models, threshold_cm=0.5, max_iter=10)
    root = tmp_path_factory.mktemp("latent")
    layout = Layout.from_paths({k: str(root / k) for k in ("data", "models", "metrics", "reports")})
    files.save_fitted(layout.rig_models("face") / "latent" / "fit", fitted)
    files.save_table(layout.rig_models("face") / "latent" / "match", table)
    return layout, fitted, table


def _latent_copy(latent, tmp_path) -> tuple[Layout, pathlib.Path]:
    layout = latent[0]
    source = layout.rig_models("face")
    copy = Layout.from_paths(
        {k: str(tmp_path / k) for k in ("data", "models", "metrics", "reports")}
    )
    shutil.copytree(source, copy.rig_models("face"))
    return copy, copy.rig_models("face") / "latent"


def test_latent_models_load_with_the_fitted_numbers_bit_for_bit(latent, tmp_path):
    from rigmap.latent import steps

    layout, fitted, table = latent
    loaded, loaded_table = steps.load_fitted(layout, "face"), steps.load_table(layout, "face")
    for label, model in fitted.models.items():
        X = model.latent[:5] + 0.01
        again = loaded.models[label]
        assert np.array_equal(again.to_controls(X), model.to_controls(X))
        P = fitted.sets[label].values[:4]
        assert np.array_equal(again.project(P, max_iter=5), model.project(P, max_iter=5))
        assert loaded.sets[label].names == fitted.sets[label].names
    for pair, match in table.matches.items():
        assert np.array_equal(loaded_table.matches[pair].target_points, match.target_points)


def test_latent_pickle_planted_as_the_models_payload_is_refused_and_not_run(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)
    marker = tmp_path / "ran"
    _plant(folder / "fit" / "models.npz", pickle.dumps(_Touch(marker)))
    with pytest.raises(ModelFileError, match="not an npz of plain arrays") as error:
        steps.load_fitted(layout, "face")
    _one_line(error, "models.json")
    assert not marker.exists()


def test_latent_pickle_planted_for_synth_run_is_a_one_line_cli_error(latent, tmp_path):
    """The reported trial: ``rigmap synth run … paths.models=<dir>`` with a crafted file."""
    import subprocess
    import sys

    layout, folder = _latent_copy(latent, tmp_path)
    marker = tmp_path / "ran"
    _plant(folder / "fit" / "models.npz", pickle.dumps(_Touch(marker)))
    root = pathlib.Path(__file__).resolve().parents[1]
    command = [sys.executable, "-m", "rigmap.cli", "synth", "run", "roar_after_idle"]
    command += ["rig=face", f"paths.models={layout.models}"]  # overrides right after the script
    command += ["--out", str(tmp_path / "out.parquet"), "--config-dir", str(root / "conf")]
    done = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 2, done.stderr[-2000:]
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "models.json" in lines[0] and "not an npz" in lines[0], lines
    assert not marker.exists() and not (tmp_path / "out.parquet").exists()


def test_latent_old_models_pkl_alone_is_never_read(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)
    marker = tmp_path / "ran"
    for name in ("models.json", "models.npz"):
        (folder / "fit" / name).unlink()
    (folder / "fit" / "models.pkl").write_bytes(pickle.dumps(_Touch(marker)))
    with pytest.raises(FileNotFoundError, match="run the latent fit step first") as error:
        steps.load_fitted(layout, "face")
    _one_line(error, "models.json")
    assert not marker.exists()


def test_latent_pickle_planted_as_the_transitions_payload_is_refused(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)
    marker = tmp_path / "ran"
    _plant(folder / "match" / "transitions.npz", pickle.dumps(_Touch(marker)))
    with pytest.raises(ModelFileError, match="not an npz of plain arrays") as error:
        steps.load_table(layout, "face")
    _one_line(error, "transitions.json")
    assert not marker.exists()


def _rewrite_npz(payload: pathlib.Path, change) -> None:
    with np.load(payload, allow_pickle=False) as data:
        arrays = {k: data[k] for k in data.files}
    change(arrays)
    scratch = payload.with_name("scratch.npz")
    np.savez(scratch, **arrays)
    _plant(payload, scratch.read_bytes())
    scratch.unlink()


def test_latent_model_missing_an_array_is_refused(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)
    _rewrite_npz(folder / "fit" / "models.npz", lambda a: a.pop("model1.gplvm.alpha"))
    with pytest.raises(ModelFileError, match=r"\['model1.gplvm.alpha'\] are missing") as error:
        steps.load_fitted(layout, "face")
    _one_line(error, "models.json")


def test_latent_model_with_a_wrong_shape_is_refused(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)

    def cut(arrays):
        arrays["model0.gplvm.L"] = arrays["model0.gplvm.L"][:-1]

    _rewrite_npz(folder / "fit" / "models.npz", cut)
    with pytest.raises(ModelFileError, match=r"array 'gplvm.L' has shape") as error:
        steps.load_fitted(layout, "face")
    _one_line(error, "models.json", "happy")


def test_latent_model_of_another_format_version_is_refused(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)
    meta_path = folder / "fit" / "models.json"
    meta_path.write_text(json.dumps({**json.loads(meta_path.read_text()), "format_version": 0}))
    with pytest.raises(ModelFileError, match="format_version 0, expected 1") as error:
        steps.load_fitted(layout, "face")
    _one_line(error, "models.json")


def test_latent_payload_path_leaving_the_model_folder_is_refused(latent, tmp_path):
    from rigmap.latent import steps

    layout, folder = _latent_copy(latent, tmp_path)
    shutil.copy(folder / "fit" / "models.npz", tmp_path / "x.npz")
    meta_path = folder / "fit" / "models.json"
    meta = json.loads(meta_path.read_text())
    depth = len(meta_path.parent.relative_to(tmp_path).parts)
    meta_path.write_text(json.dumps({**meta, "payload": "../" * depth + "x.npz"}))
    with pytest.raises(ModelFileError, match="outside the model folder") as error:
        steps.load_fitted(layout, "face")
    _one_line(error, "models.json")


# --------------------------------------------------------------------------- edits
@pytest.fixture(scope="module")
def edit_model(tmp_path_factory):
    """A small real edit model of the biped (two clips, MLS: quick), saved by the stage's writer."""
    import rigmap.rigs
    from rigmap.edits.procedural import Edit
    from rigmap.edits.propagation import EditModel, save_model
    from rigmap.edits.representation import ChannelScale
    from rigmap.edits.subjects import rig_clip, rig_subject

    rig = rigmap.rigs.load("biped")
    subject = rig_subject(rig)
    clips = [rig_clip(rig, subject.channels, name, 0) for name in ("Walk", "Idle")]
    config_file = (
        pathlib.Path(__file__).resolve().parents[1] / "conf/edit/arms_forward_walking.yaml"
    )
    edit = Edit.from_config("arms_forward_walking", yaml.safe_load(config_file.read_text()), "rig")
    pairs = [(subject.source(c), edit.apply(c)) for c in clips]
    model = EditModel(subject.joints, residual=True, estimator="mls")
    model.fit(pairs, ChannelScale.fit(clips))
    path = tmp_path_factory.mktemp("edits") / "arms.npz"
    save_model(model, path)
    return path, model, subject.source(clips[0])


def _edit_copy(edit_model, tmp_path) -> pathlib.Path:
    path = edit_model[0]
    for suffix in (".npz", ".json"):
        shutil.copy(path.with_suffix(suffix), tmp_path / f"arms{suffix}")
    return tmp_path / "arms.npz"


def test_edit_model_loads_with_the_fitted_numbers(edit_model, tmp_path):
    from rigmap.edits.propagation import load_model

    _, model, source = edit_model
    again = load_model(_edit_copy(edit_model, tmp_path))
    assert np.array_equal(again.apply(source).values, model.apply(source).values)


def test_edit_pickle_planted_as_the_model_is_refused_and_not_run(edit_model, tmp_path):
    from rigmap.edits.propagation import load_model

    path = _edit_copy(edit_model, tmp_path)
    marker = tmp_path / "ran"
    _plant(path, pickle.dumps(_Touch(marker)))
    with pytest.raises(ModelFileError, match="not an npz of plain arrays") as error:
        load_model(path)
    _one_line(error, "arms.json")
    assert not marker.exists()


def test_edit_model_without_its_json_is_refused(edit_model, tmp_path):
    from rigmap.edits.propagation import load_model

    path = _edit_copy(edit_model, tmp_path)
    path.with_suffix(".json").unlink()
    with pytest.raises(ModelFileError, match=r"no edit_model model here \(expected arms.json"):
        load_model(path)


def test_edit_model_missing_an_array_or_with_a_wrong_shape_is_refused(edit_model, tmp_path):
    from rigmap.edits.propagation import load_model

    path = _edit_copy(edit_model, tmp_path)
    _rewrite_npz(path, lambda a: a.pop("std"))
    with pytest.raises(ModelFileError, match=r"arrays \['std'\] are missing") as error:
        load_model(path)
    _one_line(error, "arms.json")
    path = _edit_copy(edit_model, tmp_path)

    def widen(arrays):
        arrays["kinematic_B_"] = np.hstack([arrays["kinematic_B_"], arrays["kinematic_B_"]])

    _rewrite_npz(path, widen)
    wrong = r"kinematic GP\): array 'kinematic_B_' has shape"
    with pytest.raises(ModelFileError, match=wrong) as error:
        load_model(path)
    _one_line(error, "arms.json")


def test_edit_model_with_an_object_array_is_refused_not_unpickled(edit_model, tmp_path):
    from rigmap.edits.propagation import load_model

    path = _edit_copy(edit_model, tmp_path)
    marker = tmp_path / "ran"

    def plant(arrays):
        arrays["channels"] = np.array([_Touch(marker)], dtype=object)

    _rewrite_npz(path, plant)
    with pytest.raises(ModelFileError, match="unreadable array") as error:
        load_model(path)
    _one_line(error, "arms.json")
    assert not marker.exists()


# --------------------------------------------------------------------------- regression / map
@pytest.fixture(scope="module")
def gpr_folder(tmp_path_factory):
    rng = np.random.default_rng(0)
    X, Y = rng.normal(size=(20, 4)), rng.normal(size=(20, 2))
    gpr = GaussianProcessRegressor(n_points=10, n_length_scales=2, cv_splits=2, progress=False)
    return gpr.fit(X, Y).save(tmp_path_factory.mktemp("gpr") / "gpr"), X


def _gpr_copy(gpr_folder, tmp_path) -> pathlib.Path:
    return shutil.copytree(gpr_folder[0], tmp_path / "gpr")


def test_regression_pickle_planted_as_the_payload_is_refused_and_not_run(gpr_folder, tmp_path):
    folder = _gpr_copy(gpr_folder, tmp_path)
    marker = tmp_path / "ran"
    _plant(folder / "gpr.npz", pickle.dumps(_Touch(marker)))
    with pytest.raises(ModelFileError, match="not an npz of plain arrays") as error:
        load_regressor(folder)
    _one_line(error, "gpr")
    assert not marker.exists()


@pytest.mark.parametrize("payload", ["../../x.npz", "/etc/passwd", "", "."])
def test_regression_payload_path_outside_the_folder_is_refused(gpr_folder, tmp_path, payload):
    folder = _gpr_copy(gpr_folder, tmp_path)
    shutil.copy(folder / "gpr.npz", tmp_path / "x.npz")
    meta = json.loads((folder / "gpr.json").read_text())
    (folder / "gpr.json").write_text(json.dumps({**meta, "payload": payload}))
    with pytest.raises(ModelFileError, match="payload") as error:
        load_regressor(folder)
    _one_line(error, "gpr.json")


_OPENED: list[str] | None = None  # while a list, every file opened is recorded in it


def _record_open(event: str, args: tuple) -> None:
    if event == "open" and _OPENED is not None and isinstance(args[0], (str, bytes, os.PathLike)):
        _OPENED.append(os.fsdecode(args[0]))


_MODULE_FILES = (".py", ".pyc", ".so")  # a lazy import opens these: not model data
sys.addaudithook(_record_open)  # audit hooks cannot be removed; this one records only on demand


@pytest.mark.parametrize(
    "outside", ["../../x.npz", "/etc/passwd"], ids=["payload_dot_dot_x_npz", "payload_etc_passwd"]
)
def test_regression_payload_outside_with_its_true_hash_is_never_read(gpr_folder, tmp_path, outside):
    """Trial 4: ``"payload": "../../x.npz"`` or ``"/etc/passwd"`` signed with that file's
    true hash is refused before it is opened (an audit hook records every open)."""
    global _OPENED
    folder = _gpr_copy(gpr_folder, tmp_path / "a" / "b")
    target = (folder / outside).resolve()
    if outside.startswith(".."):
        shutil.copy(folder / "gpr.npz", target)
    meta = json.loads((folder / "gpr.json").read_text())
    meta.update(payload=outside, payload_sha256=hashlib.sha256(target.read_bytes()).digest().hex())
    (folder / "gpr.json").write_text(json.dumps(meta))
    _OPENED = []
    try:
        with pytest.raises(ModelFileError, match="outside the model folder") as error:
            load_regressor(folder)
        opened = [pathlib.Path(n).resolve() for n in _OPENED if not n.endswith(_MODULE_FILES)]
    finally:
        _OPENED = None
    _one_line(error, "gpr.json", repr(outside))
    assert opened and all(path.is_relative_to(folder.resolve()) for path in opened), opened


def test_regression_payload_symlinked_out_of_the_folder_is_refused(gpr_folder, tmp_path):
    folder = _gpr_copy(gpr_folder, tmp_path)
    outside = tmp_path / "elsewhere.npz"
    shutil.move(folder / "gpr.npz", outside)
    (folder / "gpr.npz").symlink_to(outside)
    with pytest.raises(ModelFileError, match="outside the model folder") as error:
        load_regressor(folder)
    _one_line(error, "gpr.json")


# --------------------------------------------------------------------------- MLflow pyfunc
@pytest.fixture(scope="module")
def pyfunc_folder(gpr_folder, tmp_path_factory):
    """The GPR saved as rigmap's pyfunc model (loader_module, data/inverse_mapping)."""
    import mlflow

    from rigmap.tracking.pyfunc_model import DATA_FOLDER, INTERFACE_FORMAT, LOADER_MODULE

    data = tmp_path_factory.mktemp("pyfunc") / DATA_FOLDER
    shutil.copytree(gpr_folder[0], data / "mapping")
    interface = {"format": INTERFACE_FORMAT, "mapping_class": "GaussianProcessRegressor"}
    interface |= {"input_columns": ["a.x", "a.y", "a.z", "b.x"], "output_columns": ["c0", "c1"]}
    (data / "interface.json").write_text(json.dumps(interface))
    folder = data.parent / "model"
    mlflow.pyfunc.save_model(str(folder), loader_module=LOADER_MODULE, data_path=str(data))
    return folder, interface["input_columns"]


def test_pyfunc_model_holds_no_code_and_predicts(pyfunc_folder, gpr_folder, tmp_path):
    import pandas as pd

    from rigmap.tracking.pyfunc_model import load_pyfunc_model

    folder, columns = pyfunc_folder
    assert not [p for p in folder.rglob("*.py")] and not [p for p in folder.rglob("*.pkl")]
    model = load_pyfunc_model(str(shutil.copytree(folder, tmp_path / "model")))
    X = gpr_folder[1][:3]
    predicted = model.predict(pd.DataFrame(X, columns=columns)).to_numpy()
    expected = load_regressor(gpr_folder[0]).predict(X)
    np.testing.assert_allclose(predicted, expected, rtol=0, atol=1e-9)


def test_pyfunc_code_file_added_to_the_folder_is_not_run(pyfunc_folder, tmp_path):
    """The old layout ran the folder's own entry file; now none is read."""
    from rigmap.tracking.pyfunc_model import load_pyfunc_model

    folder = shutil.copytree(pyfunc_folder[0], tmp_path / "model")
    marker = tmp_path / "ran"
    for name in ("python_model.py", "pyfunc_entry.py", "data/inverse_mapping/__init__.py"):
        (folder / name).write_text(f"import pathlib\npathlib.Path({str(marker)!r}).touch()\n")
    load_pyfunc_model(str(folder))
    assert not marker.exists()


@pytest.mark.parametrize(
    "change",
    [
        {"loader_module": "mlflow.pyfunc.model", "python_model": "python_model.pkl"},
        {"code": "code"},
        {"loader_module": "os"},
    ],
    ids=["cloudpickled_python_model", "code_paths", "another_module"],
)
def test_pyfunc_mlmodel_tampered_to_run_code_is_refused(pyfunc_folder, tmp_path, change):
    from rigmap.tracking import UntrustedModelError
    from rigmap.tracking.pyfunc_model import load_pyfunc_model

    folder = shutil.copytree(pyfunc_folder[0], tmp_path / "model")
    marker = tmp_path / "ran"
    (folder / "python_model.pkl").write_bytes(pickle.dumps(_Touch(marker)))
    (folder / "code").mkdir()
    (folder / "code" / "rigmap.py").write_text(f"open({str(marker)!r}, 'w')\n")
    config = yaml.safe_load((folder / "MLmodel").read_text())
    config["flavors"]["python_function"].update(change)
    (folder / "MLmodel").write_text(yaml.safe_dump(config))
    with pytest.raises(UntrustedModelError, match="the model is refused") as error:
        load_pyfunc_model(str(folder))
    _one_line(error, "MLmodel")
    assert not marker.exists()


def test_pyfunc_data_path_leaving_the_model_folder_is_refused(pyfunc_folder, tmp_path):
    from rigmap.tracking import UntrustedModelError
    from rigmap.tracking.pyfunc_model import load_pyfunc_model

    folder = shutil.copytree(pyfunc_folder[0], tmp_path / "model")
    shutil.copytree(folder / "data", tmp_path / "data")
    config = yaml.safe_load((folder / "MLmodel").read_text())
    config["flavors"]["python_function"]["data"] = "../data/inverse_mapping"
    (folder / "MLmodel").write_text(yaml.safe_dump(config))
    with pytest.raises(UntrustedModelError, match="is not data/inverse_mapping") as error:
        load_pyfunc_model(str(folder))
    _one_line(error, "MLmodel")


def test_pyfunc_mapping_payload_path_leaving_the_folder_is_refused(pyfunc_folder, tmp_path):
    from rigmap.tracking.pyfunc_model import load_pyfunc_model

    folder = shutil.copytree(pyfunc_folder[0], tmp_path / "model")
    meta_path = folder / "data" / "inverse_mapping" / "mapping" / "gpr.json"
    shutil.copy(meta_path.with_name("gpr.npz"), tmp_path / "x.npz")
    meta_path.write_text(
        json.dumps({**json.loads(meta_path.read_text()), "payload": "../../../../x.npz"})
    )
    with pytest.raises(ModelFileError, match="outside the model folder") as error:
        load_pyfunc_model(str(folder))
    _one_line(error, "gpr.json")


# --------------------------------------------------------------------------- map model folder
@pytest.fixture(scope="module")
def map_folder(biped, tmp_path_factory):
    """A partial-input map model (rigmap map's cache or model= folder) of the biped."""
    from rigmap.map.partial import JointSubset, SubsetMapping
    from test_map_partial import EFFECTORS, gpr, random_poses

    Y, X, _ = random_poses(biped, 60, seed=0)
    subset = JointSubset.from_mapping(EFFECTORS, name="effectors", rig=biped)
    folder = tmp_path_factory.mktemp("map") / "map-effectors"
    SubsetMapping.fit(biped, subset, X, Y, gpr(60)).save(folder)
    return folder


def test_map_model_pickle_planted_as_its_payload_is_refused_and_not_run(
    biped, map_folder, tmp_path
):
    from rigmap.map.partial import SubsetMapping

    folder = shutil.copytree(map_folder, tmp_path / "map-effectors")
    marker = tmp_path / "ran"
    _plant(folder / "gpr.npz", pickle.dumps(_Touch(marker)))
    with pytest.raises(ModelFileError, match="not an npz of plain arrays") as error:
        SubsetMapping.load(folder, biped)
    _one_line(error, "map-effectors")
    assert not marker.exists()


def test_map_model_payload_path_leaving_its_folder_is_refused(biped, map_folder, tmp_path):
    from rigmap.map.partial import SubsetMapping

    folder = shutil.copytree(map_folder, tmp_path / "map-effectors")
    shutil.copy(folder / "gpr.npz", tmp_path / "x.npz")
    meta = json.loads((folder / "gpr.json").read_text())
    (folder / "gpr.json").write_text(json.dumps({**meta, "payload": "../x.npz"}))
    with pytest.raises(ModelFileError, match="outside the model folder") as error:
        SubsetMapping.load(folder, biped)
    _one_line(error, "gpr.json")


@pytest.mark.parametrize("text", ["flavors: {python_function: junk}\n", "[1, 2\n", ""])
def test_pyfunc_mlmodel_that_is_not_a_pyfunc_description_is_refused(pyfunc_folder, tmp_path, text):
    from rigmap.tracking import UntrustedModelError
    from rigmap.tracking.pyfunc_model import load_pyfunc_model

    folder = shutil.copytree(pyfunc_folder[0], tmp_path / "model")
    (folder / "MLmodel").write_text(text)
    with pytest.raises(UntrustedModelError, match="not a readable pyfunc MLmodel") as error:
        load_pyfunc_model(str(folder))
    _one_line(error, "MLmodel")
