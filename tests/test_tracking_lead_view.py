"""The lead's view in MLflow (issue #43, item 5): datasets, Table 1 and the README's link.

A tiny evaluation of the face rig (five methods of Table 1, the mean among them, five
frames a clip) runs through the evaluate stage's own code (``rigmap evaluate``'s call) onto
a real ``mlflow server``; the tests read back what it logged and open the README's link in
Chromium.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import urllib.parse
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.tracking import DataFile, dataset_input, file_md5, runs_view_url, ui_base_url

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("gpr", "gpr_learned_jacobian", "nn", "nn_autodiff_jacobian", "mean")
SAMPLES = 40
UI_TIMEOUT_MS = 60_000  # the React app on a loaded 2-core machine
#: an experiment (and no registered models) of its own on the session's shared server, on
#: which other files' tests count the runs and model versions of ``rigmap-face``
PREFIX = "leadview"


# --------------------------------------------------------------------------- no server
def test_the_digest_is_dvcs_md5_of_the_file(tmp_path):
    from dvc_data.hashfile.hash import file_md5 as dvc_file_md5

    path = tmp_path / "train.parquet"
    pd.DataFrame({"clip": ["a", "b"], "frame": [0, 1], "ctrl": [0.5, 1.5]}).to_parquet(path)
    assert file_md5(path) == dvc_file_md5(str(path)) == _md5(path)
    logged = dataset_input(DataFile(path, "face-corpus-train", "training"))
    assert logged.dataset.digest == file_md5(path)
    assert [(t.key, t.value) for t in logged.tags] == [("mlflow.data.context", "training")]
    assert json.loads(logged.dataset.profile) == {"num_rows": 2, "num_columns": 3}
    columns = json.loads(logged.dataset.schema)["mlflow_colspec"]
    assert [(c["name"], c["type"]) for c in columns] == [
        ("clip", "string"), ("frame", "long"), ("ctrl", "double"),
    ]  # fmt: skip
    assert json.loads(logged.dataset.source) == {"uri": path.resolve().as_uri()}


def test_an_npz_is_described_from_its_headers(tmp_path):
    path = tmp_path / "pca_gaussian.npz"
    np.savez(path, controls=np.zeros((7, 3)), meta=np.array("{}"))
    logged = dataset_input(DataFile(path, "face-samples-pca_gaussian", "samples"))
    assert json.loads(logged.dataset.profile) == {"arrays": {"controls": [7, 3], "meta": []}}
    assert logged.dataset.digest == _md5(path)


def test_a_missing_file_or_unknown_context_is_one_line(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"gone\.parquet: dataset 'x' \(test\) is missing"):
        dataset_input(DataFile(tmp_path / "gone.parquet", "x", "test"))
    with pytest.raises(ValueError, match="context 'validation' is not one of"):
        DataFile(tmp_path / "a.parquet", "x", "validation")


def test_the_link_opens_the_saved_view_of_the_runs_list():
    assert runs_view_url("http://127.0.0.1:5000/", "7") == (
        "http://127.0.0.1:5000/#/experiments/7/runs?viewStateShareKey=rigmap-methods"
    )
    assert ui_base_url("http://host:5000/") == "http://host:5000"
    assert ui_base_url("sqlite:////work/mlruns.db") is None


# --------------------------------------------------------------------------- a real evaluation
@pytest.fixture(scope="module")
def lead_run(mlflow_server, tmp_path_factory):
    """The face corpus, tiny fitted mappings and real pca_gaussian samples, evaluated with
    MLflow logging on; returns the server, folders, printed link and the runs."""
    from mlflow import MlflowClient

    from rigmap.animation.corpus import Corpus
    from rigmap.app.evaluate import evaluate_command
    from rigmap.rigs import load
    from rigmap.sampling import make_sampler, supersample
    from test_methods import build_rig_data, fit_tiny_models

    rig = load("face")
    root = tmp_path_factory.mktemp("lead_view")
    data = build_rig_data(rig, root / "data")
    fit_tiny_models(rig, data, root / "models")
    corpus = Corpus.read(data / "corpus" / "train.parquet", control_names=rig.used_controls)
    sampler = make_sampler("pca_gaussian").fit(corpus.values())
    supersample(
        rig, sampler, SAMPLES, data / "samples" / "pca_gaussian.npz", seed=0, progress=False
    )
    overrides = [
        "rig=face", f"paths.data={root / 'data'}", f"paths.models={root / 'models'}",
        f"paths.metrics={root / 'metrics'}", f"tracking.uri={mlflow_server}",
        f"evaluate.methods=[{','.join(METHODS)}]", "evaluate.frames_per_clip=5",
        "evaluate.progress=false", f"tracking.experiment_prefix={PREFIX}",
        "tracking.register_models=false",
    ]  # fmt: skip
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        evaluate_command(overrides)  # `rigmap evaluate`: the stage's own code, in this process
    client = MlflowClient(mlflow_server)
    experiment = client.get_experiment_by_name(f"{PREFIX}-face")
    runs = client.search_runs([experiment.experiment_id])
    (parent,) = [r for r in runs if r.data.tags.get("kind") == "sweep"]
    children = {
        r.data.tags["method"]: r
        for r in runs
        if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id
    }
    link = re.findall(r"^MLflow: each method .*: (\S+)$", printed.getvalue(), re.MULTILINE)
    return {
        "server": mlflow_server, "client": client, "experiment": experiment, "parent": parent,
        "children": children, "data": data, "metrics": root / "metrics" / "face" / "methods",
        "link": link,
    }  # fmt: skip


def _inputs(run) -> dict[str, tuple[str, str]]:
    """name -> (digest, context) of a run's datasets."""
    return {
        i.dataset.name: (i.dataset.digest, {t.key: t.value for t in i.tags}["mlflow.data.context"])
        for i in run.inputs.dataset_inputs
    }


def test_the_files_read_are_datasets_with_their_dvc_md5(lead_run):
    data = lead_run["data"]
    files = {
        "face-corpus-train": (data / "corpus" / "train.parquet", "training"),
        "face-corpus-test": (data / "corpus" / "test.parquet", "test"),
        "face-poses-test": (data / "poses" / "test.parquet", "test"),
        "face-samples-pca_gaussian": (data / "samples" / "pca_gaussian.npz", "samples"),
    }
    expected = {name: (_md5(path), context) for name, (path, context) in files.items()}
    assert _inputs(lead_run["parent"]) == expected
    children = lead_run["children"]
    assert sorted(children) == sorted(METHODS)
    for method, run in children.items():
        learned_from_samples = run.data.tags["sampler"] == "pca_gaussian"  # the networks
        used = set(files) - (set() if learned_from_samples else {"face-samples-pca_gaussian"})
        assert _inputs(run) == {name: expected[name] for name in used}, method
    samples = next(
        i.dataset
        for i in children["nn"].inputs.dataset_inputs
        if i.dataset.name.endswith("gaussian")
    )
    assert json.loads(samples.profile)["arrays"]["controls"][0] == SAMPLES


def test_the_parent_holds_table1_with_every_methods_rows(lead_run, tmp_path):
    client, parent = lead_run["client"], lead_run["parent"]
    path = client.download_artifacts(parent.info.run_id, "table1.json", str(tmp_path))
    table = pd.read_json(path, orient="split")
    averages = table[table["motion"] == "Average"].set_index("method")
    assert sorted(averages.index) == sorted(METHODS)
    for method, run in lead_run["children"].items():
        saved = json.loads(
            (lead_run["metrics"] / f"{method}-{run.data.tags['sampler']}.json").read_text()
        )
        row = averages.loc[method]
        assert row["run_id"] == run.info.run_id
        for key in ("joint_error", "ground_truth_error", "fps", "total_time_s"):
            # MLflow writes a table's numbers with 10 decimals (pandas' to_json default)
            assert row[key] == pytest.approx(saved["average"][key], abs=1e-10), (method, key)
        clips = table[(table["method"] == method) & (table["motion"] != "Average")]
        assert sorted(clips["motion"]) == sorted(saved["clips"])


def test_the_saved_view_lists_the_children_by_joint_error(lead_run):
    client, experiment = lead_run["client"], lead_run["experiment"]
    envelope = json.loads(experiment.tags["mlflow.sharedViewState.rigmap-methods"])
    assert envelope["name"] == "Table 1 (methods), latest evaluation"
    state = json.loads(envelope["state"])
    assert state["selectedColumns"][:5] == [
        "tags.`method`", "tags.`sampler`", "metrics.`joint_error`",
        "metrics.`ground_truth_error`", "metrics.`fps`",
    ]  # fmt: skip
    # the view's filter and sort, as the server runs them: this evaluation's children only
    found = client.search_runs(
        [experiment.experiment_id], state["searchFilter"], order_by=["metrics.joint_error ASC"]
    )
    children = lead_run["children"]
    by_error = sorted(children, key=lambda m: children[m].data.metrics["joint_error"])
    assert [r.data.tags["method"] for r in found] == by_error
    assert state["orderByKey"] == "metrics.`joint_error`" and state["orderByAsc"] is True


def test_the_cli_prints_the_link_and_names_a_missing_view(lead_run, capsys):
    from rigmap.cli import main

    server = lead_run["server"]
    store = [f"tracking.uri={server}", f"tracking.experiment_prefix={PREFIX}"]
    expected = runs_view_url(server, lead_run["experiment"].experiment_id)
    assert lead_run["link"] == [expected]  # the evaluation's last word
    assert main(["tracking", "url", "--rig", "face", *store]) == 0
    assert capsys.readouterr().out.strip() == expected
    assert main(["tracking", "url", "--rig", "face", "--view", "samplers", *store]) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0
    assert "no saved view 'rigmap-samplers' (there are: rigmap-methods)" in error
    assert main(["tracking", "url", "--rig", "nobody", *store]) == 2
    assert f"no experiment '{PREFIX}-nobody'" in capsys.readouterr().err


@pytest.mark.browser
def test_the_readmes_link_shows_every_method_with_its_joint_error_and_the_datasets(lead_run):
    from playwright.sync_api import expect

    from browser import chromium_page

    experiment_id = lead_run["experiment"].experiment_id
    link = _readme_link().replace("http://127.0.0.1:5000", lead_run["server"])
    link = link.replace("<experiment_id>", experiment_id)
    assert link == runs_view_url(lead_run["server"], experiment_id)
    children = lead_run["children"]
    with chromium_page(link, viewport={"width": 1600, "height": 900}) as page:
        table = page.locator(".ag-root")  # the runs list (ag-grid)
        expect(table).to_contain_text("joint_error", timeout=UI_TIMEOUT_MS)
        for method, run in children.items():
            expect(table).to_contain_text(run.info.run_name, timeout=UI_TIMEOUT_MS)
            cells = table.locator(f'[row-id="{run.info.run_id}"]')
            expect(cells.first).to_be_attached(timeout=UI_TIMEOUT_MS)
            text = " ".join(cells.all_inner_texts())  # the row's pinned and scrolled parts
            assert method in text.split(), (method, text)
            assert _js_number(run.data.metrics["joint_error"]) in text.split(), (method, text)
            for name, (digest, _) in _inputs(run).items():
                assert f"{name} ({digest})" in text, (method, name, text)
        shown = {
            table.locator("[row-id]").nth(i).get_attribute("row-id")
            for i in range(table.locator("[row-id]").count())
        }
        assert shown == {run.info.run_id for run in children.values()}  # no parent, no others


# --------------------------------------------------------------------------- helpers
def _md5(path: Path) -> str:
    import hashlib

    return hashlib.md5(Path(path).read_bytes()).hexdigest()


def _readme_link() -> str:
    """The runs-list link the README gives, for `make tracking-server`'s address."""
    found = re.findall(
        r"http://127\.0\.0\.1:5000/#/experiments/\S+", (ROOT / "README.md").read_text()
    )
    assert len(found) == 1, found
    return urllib.parse.unquote(found[0].rstrip("`)"))


def _js_number(value: float) -> str:
    """How the UI's table writes a metric (JavaScript's shortest round-trip form)."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))
