"""Faults in logged models: a model in a shared registry is data, never code (issue 20, defect 1).

A real network mapping is saved as a pyfunc model folder the way ``log_inverse_mapping``
lays it out (``MLmodel`` naming rigmap's loader, ``data/inverse_mapping/mapping`` and
``.../interface.json``); then the folder is tampered with as an attacker with write
access to the registry would.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from rigmap.regression import FeedForwardRegressor
from rigmap.tracking import UntrustedModelError
from rigmap.tracking.pyfunc_model import (
    DATA_FOLDER,
    INTERFACE_FORMAT,
    LOADER_MODULE,
    MAPPING_ARTIFACT,
    mapping_class_name,
)

INPUTS = [f"j{i}.{axis}" for i in range(2) for axis in "xyz"]
OUTPUTS = ["c0", "c1"]


@pytest.fixture(scope="module")
def model_folder(tmp_path_factory):
    """A real saved pyfunc model of a small fitted network, and its predictions on a probe."""
    import mlflow

    scratch = tmp_path_factory.mktemp("model") / DATA_FOLDER
    scratch.mkdir()
    rng = np.random.default_rng(3)
    X = rng.normal(size=(40, len(INPUTS)))
    Y = X[:, :2] * 2.0 + 1.0
    mapping = FeedForwardRegressor(hidden=8, epochs=2, batch_size=8, progress=False).fit(X, Y)
    mapping.save(scratch / "mapping")
    interface = {
        "format": INTERFACE_FORMAT,
        "mapping_class": mapping_class_name(FeedForwardRegressor),
        "rig": "test",
        "regressor": "nn",
        "input_columns": INPUTS,
        "output_columns": OUTPUTS,
    }
    (scratch / "interface.json").write_text(json.dumps(interface), encoding="utf-8")
    folder = scratch.parent / "model"
    mlflow.pyfunc.save_model(str(folder), loader_module=LOADER_MODULE, data_path=str(scratch))
    probe = pd.DataFrame(X[:3], columns=INPUTS)
    return folder, probe, mapping.predict(X[:3])


def _copy(model_folder, tmp_path) -> Path:
    copy = tmp_path / "model"
    shutil.copytree(model_folder, copy, symlinks=True)
    return copy


def _load(folder: Path):
    import mlflow

    return mlflow.pyfunc.load_model(str(folder))


def test_untouched_model_loads_and_predicts(model_folder, tmp_path):
    folder, probe, expected = model_folder
    predicted = _load(_copy(folder, tmp_path)).predict(probe)
    np.testing.assert_allclose(predicted.to_numpy(), expected, rtol=0, atol=1e-6)


def test_tampered_interface_naming_a_module_is_refused_without_importing_it(
    model_folder, tmp_path, monkeypatch
):
    """Defect 1: interface.json's mapping_class was imported and its load() called."""
    folder = _copy(model_folder[0], tmp_path)
    marker = tmp_path / "payload_ran"
    payload = tmp_path / "payload_mod"
    payload.mkdir()
    (payload / "evil_mapping.py").write_text(
        f"from pathlib import Path\nPath({str(marker)!r}).write_text('ran')\n"
        "class Mapping:\n    @classmethod\n    def load(cls, path):\n        return cls()\n"
    )
    monkeypatch.syspath_prepend(str(payload))
    interface_file = folder / "data" / DATA_FOLDER / "interface.json"
    interface = json.loads(interface_file.read_text())
    interface["mapping_class"] = "evil_mapping:Mapping"
    interface_file.write_text(json.dumps(interface))
    with pytest.raises(UntrustedModelError, match=r"interface\.json: mapping_class 'evil_mapping"):
        _load(folder)
    assert not marker.exists() and "evil_mapping" not in sys.modules


def test_interface_naming_a_stdlib_callable_is_refused(model_folder, tmp_path):
    folder = _copy(model_folder[0], tmp_path)
    interface_file = folder / "data" / DATA_FOLDER / "interface.json"
    interface = json.loads(interface_file.read_text())
    interface["mapping_class"] = "subprocess:Popen"
    interface_file.write_text(json.dumps(interface))
    with pytest.raises(UntrustedModelError, match="not one of rigmap's mapping classes"):
        _load(folder)


def test_payload_path_with_dot_dot_leaving_the_model_folder_is_refused(model_folder, tmp_path):
    """Defect 1: MLmodel's data path ``../outside/...`` was followed out of the folder."""
    folder = _copy(model_folder[0], tmp_path)
    shutil.copytree(folder / "data" / DATA_FOLDER, tmp_path / "outside" / DATA_FOLDER)
    mlmodel = folder / "MLmodel"
    config = yaml.safe_load(mlmodel.read_text())
    config["flavors"]["python_function"]["data"] = f"../outside/{DATA_FOLDER}"
    mlmodel.write_text(yaml.safe_dump(config))
    with pytest.raises(UntrustedModelError, match=r"keeps its data in data/inverse_mapping"):
        _load(folder)


def test_symlink_inside_the_mapping_folder_leading_out_is_refused(model_folder, tmp_path):
    folder = _copy(model_folder[0], tmp_path)
    secret = tmp_path / "secret.txt"
    secret.write_text("not the model's")
    (folder / "data" / DATA_FOLDER / MAPPING_ARTIFACT / "extra.json").symlink_to(secret)
    with pytest.raises(UntrustedModelError, match=r"extra\.json.*outside the model folder"):
        _load(folder)


def test_interface_of_another_format_is_refused(model_folder, tmp_path):
    folder = _copy(model_folder[0], tmp_path)
    (folder / "data" / DATA_FOLDER / "interface.json").write_text(
        '{"mapping_class": "InverseMapping"'
    )
    with pytest.raises(UntrustedModelError, match=r"interface\.json: not a readable interface"):
        _load(folder)
