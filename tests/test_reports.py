"""The report generator and `rigmap reproduce`.

The metrics tree is synthetic but real: for each rig, ridge-regularised linear
maps from joint positions to controls are fitted on the rig's train corpus, run
on its test clips, the predicted controls go back through the rig, and the
joint and ground-truth errors and timings are computed by
``rigmap.evaluation.metrics`` and written as the evaluate stages write them.
"""

from __future__ import annotations

import html.parser
import json
import math
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from least_squares_mapping import LeastSquaresMapping
from rigmap.animation.library import build_corpus
from rigmap.evaluation.metrics import (
    ClipResult,
    MethodResult,
    control_std,
    ground_truth_error,
    joint_error,
    write_per_frame_csv,
)
from rigmap.evaluation.novelty import Novelty
from rigmap.reports import ReportInputError, ReportSettings, build_report, load_metrics, published
from rigmap.reports.figures import sweep_figure
from rigmap.reports.rig_facts import RigFacts
from rigmap.reports.tables import kernels_table, methods_table, rigs_table, sampling_table
from rigmap.rigs import load
from rigmap.store.layout import per_frame_file

ROOT = Path(__file__).resolve().parents[1]
RIGS = ("quadruped", "face")
# Table 1 on both (the pipeline's default is quadruped and biped); face has no Script row
SETTINGS = ReportSettings(rigs=RIGS, method_rigs=RIGS)
RIDGES = (1e-4, 1e-2, 1.0, 30.0)  # four real fits per rig, shared by the files


def _rig_predictions(rig, data: Path):
    """Real fits on the train corpus; per ridge: predictions on every kept test frame."""
    train = build_corpus(rig, "train", seed=0)
    test = build_corpus(rig, "test", seed=0)
    train.write(data / rig.name / "corpus" / "train.parquet")
    test.write(data / rig.name / "corpus" / "test.parquet")
    used = rig.used_controls
    table = test.table[test.table["frame"] % 8 == 0]  # every 8th frame keeps the test fast
    Y_test = table[used].to_numpy(float)
    Y_train = train.table[used].to_numpy(float)[::8]
    X_test = rig.evaluate(rig.expand_used(Y_test))
    X_train = rig.evaluate(rig.expand_used(Y_train)).reshape(len(Y_train), -1)
    std = control_std(train.table[used].to_numpy(float))
    kinds = [rig.controls.kinds[i] for i in rig.controls.used_indices]
    fits = []
    for ridge in RIDGES:
        model = LeastSquaresMapping(ridge).fit(X_train, Y_train)
        Y_pred = model.predict(X_test.reshape(len(X_test), -1))
        X_pred = rig.evaluate(rig.expand_used(Y_pred))
        fits.append(
            {
                "model": model,
                "joint": joint_error(X_pred, X_test).per_frame,
                "truth": ground_truth_error(Y_pred, Y_test, std, kinds).per_frame,
            }
        )
    return table, X_test, fits, Novelty.from_training(X_train, rig.n_joints)


def _method_result(rig, table, X_test, fit, method: str, sampler: str, novelty) -> MethodResult:
    clips = []
    flat = X_test.reshape(len(X_test), -1)
    for clip in dict.fromkeys(table["clip"]):
        rows = np.flatnonzero(table["clip"].to_numpy() == clip)
        started = time.perf_counter()
        fit["model"].predict(flat[rows])
        seconds = max(time.perf_counter() - started, 1e-9)
        clips.append(
            ClipResult(
                clip=clip,
                joint_error_per_frame=fit["joint"][rows],
                ground_truth_error_per_frame=fit["truth"][rows],
                total_time_s=seconds,
                rig_evaluations=len(rows),
                frame_numbers=table["frame"].to_numpy()[rows],
                novelty_per_frame=novelty.distances(flat[rows]),
            )
        )
    refine = "none" if "jacobian" not in method else "computed_jacobian"
    return MethodResult(
        rig=rig.name, method=method, sampler=sampler, clips=clips, extra={"refine": refine}
    )


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """data/<rig>/corpus, metrics/<rig>/..., and the report built from them."""
    root = tmp_path_factory.mktemp("report")
    data, metrics = root / "data", root / "metrics"
    expected = {}
    for rig_name in RIGS:
        rig = load(rig_name)
        table, X_test, fits, novelty = _rig_predictions(rig, data)
        files = [
            ("methods", m, f"{m}-{SETTINGS.method_sampler(m)}", m, SETTINGS.method_sampler(m))
            for m in SETTINGS.methods_for(rig_name)
        ]
        files += [("samplers", s, f"nn-{s}", "nn", s) for s in SETTINGS.samplers]
        files += [("kernels", k, f"gpr-{k}", "gpr", "none") for k in SETTINGS.kernels]
        for index, (folder, key, stem, method, sampler) in enumerate(files):
            fit = fits[index % len(RIDGES)]
            result = _method_result(rig, table, X_test, fit, method, sampler, novelty)
            json_path = result.write_json(metrics / rig_name / folder / f"{stem}.json")
            write_per_frame_csv(result, per_frame_file(json_path))
            expected[(rig_name, folder, key)] = result
    # what the sample-figures stage would leave for one rig
    (root / "reports" / "figures").mkdir(parents=True)
    shutil.copy(
        ROOT / "reports" / "figures" / "rigs" / "quadruped_random.png"
        if (ROOT / "reports" / "figures" / "rigs" / "quadruped_random.png").is_file()
        else _tiny_png(root),
        root / "reports" / "figures" / "samples_quadruped.png",
    )
    # what latent_evaluate would leave for the face (#18): two of its tables and Fig 2
    latent = metrics / "face" / "latent"
    latent.mkdir(parents=True)
    (latent / "suites.csv").write_text(
        "command,count,success_rate,frames_median,frames_max\nMOVE,6,0.5,56.5,130\n"
        "PLAY,6,1.0,108.5,122\n"
    )
    (latent / "matching.csv").write_text(
        "pair,points,candidates,spread_latent,distance_cm_median,distance_cm_max\n"
        "happy-roar,0,300,0.0,,\n"
    )
    shutil.copy(_tiny_png(root), root / "reports" / "figures" / "latent_face.png")
    files = build_report(
        metrics_root=metrics, data_root=data, reports_root=root / "reports", settings=SETTINGS
    )
    return {"root": root, "files": files, "expected": expected}


def _tiny_png(folder: Path) -> Path:
    from matplotlib.figure import Figure

    path = folder / "tiny.png"
    Figure(figsize=(1, 1)).savefig(path)
    return path


def _csv(project, name: str) -> pd.DataFrame:
    """A table's CSV; published values stay the strings the paper prints."""
    path = project["root"] / "reports" / "tables" / f"{name}.csv"
    header = pd.read_csv(path, nrows=0).columns
    as_text = {c: str for c in header if c.startswith("published")}
    return pd.read_csv(path, keep_default_na=False, dtype=as_text)


# --------------------------------------------------------------------------- tables
def test_table1_has_every_method_row_per_clip_and_average(project):
    table = _csv(project, "table1_methods")
    for rig in RIGS:
        rows = table[table["rig"] == rig]
        clips = list(project["expected"][(rig, "methods", "gpr")].to_dict()["clips"])
        assert list(dict.fromkeys(rows["motion"])) == [*clips, "Average"]
        for motion in [*clips, "Average"]:
            methods = rows[rows["motion"] == motion]["method"].tolist()
            assert methods == list(SETTINGS.methods_for(rig))
    assert "script" not in table[table["rig"] == "face"]["method"].tolist()
    assert len(SETTINGS.methods_for("quadruped")) == 12
    extras = table[table["extra"].astype(str) == "True"]["method"].unique().tolist()
    assert sorted(extras) == [
        "mean",
        "nn_autodiff_jacobian",
        "nn_joint_space",
        "nn_joint_space_computed_jacobian",
        "nn_joint_space_tuned",
        "nn_learned_jacobian",
    ]
    for column in ("joint_error", "ground_truth_error", "total_time_s", "fps"):
        values = table[column].astype(float).to_numpy()
        assert np.isfinite(values).all() and (values >= 0).all()


def test_table1_numbers_are_the_metrics_numbers(project):
    table = _csv(project, "table1_methods")
    result = project["expected"][("quadruped", "methods", "nn_computed_jacobian")]
    row = table[
        (table["rig"] == "quadruped")
        & (table["motion"] == "Average")
        & (table["method"] == "nn_computed_jacobian")
    ].iloc[0]
    assert math.isclose(row["joint_error"], result.joint_error, rel_tol=1e-12)
    assert math.isclose(row["ground_truth_error"], result.ground_truth_error, rel_tol=1e-12)
    assert row["frames"] == result.frames
    clip = result.clips[1]
    row = table[
        (table["rig"] == "quadruped")
        & (table["motion"] == clip.clip)
        & (table["method"] == "nn_computed_jacobian")
    ].iloc[0]
    assert math.isclose(row["fps"], clip.fps, rel_tol=1e-12)
    # the fits differ, so the rows do: the ridge-1e-4 fit beats the ridge-30 fit
    averages = table[(table["rig"] == "quadruped") & (table["motion"] == "Average")]
    assert averages["joint_error"].nunique() == len(RIDGES)
    markdown = (project["root"] / "reports" / "tables" / "table1_methods.md").read_text()
    assert f"| {result.joint_error:.3f} |" in markdown or f"{result.joint_error:.2e}" in markdown


def test_table1_scale_free_columns_divide_by_the_mean_predictor_row(project):
    table = _csv(project, "table1_methods")
    rows = table[table["rig"] == "quadruped"]
    for motion in rows["motion"].unique():
        at = rows[rows["motion"] == motion].set_index("method")
        baseline = at.loc["mean"]
        for _, row in at.iterrows():
            assert row["joint_rms"] == pytest.approx(math.sqrt(3 * row["joint_error"]))
            ratio = row["joint_error"] / baseline["joint_error"]
            assert row["joint_error_relative_to_mean"] == pytest.approx(ratio, rel=1e-12)
            truth = row["ground_truth_error"] / baseline["ground_truth_error"]
            assert row["ground_truth_error_relative_to_mean"] == pytest.approx(truth, rel=1e-12)
        assert at.loc["mean", "joint_error_relative_to_mean"] == pytest.approx(1.0)
    # the ridge fits of this tree write no character height: the share is left blank, not made up
    assert rows["joint_rms_percent_of_height"].astype(str).isin(["", "nan"]).all()
    html_text = (project["root"] / "reports" / "tables" / "table1_methods.md").read_text()
    assert "Joint Error (unit not stated)" in html_text and "Mean Predictor" in html_text


def test_confidence_figure_and_spearman_come_from_the_per_frame_novelty(project):
    figure = project["root"] / "reports" / "figures" / "results" / "confidence.png"
    assert figure in [f.path for f in project["files"].figures] and figure.stat().st_size > 5000
    table = _csv(project, "table1_methods")
    row = table[
        (table["rig"] == "quadruped") & (table["motion"] == "Average") & (table["method"] == "gpr")
    ].iloc[0]
    result = project["expected"][("quadruped", "methods", "gpr")]
    frames = result.per_frame_table()
    from scipy.stats import spearmanr

    expected = spearmanr(frames["novelty"], frames["joint_error"]).statistic
    assert float(row["novelty_error_spearman"]) == pytest.approx(expected, rel=1e-12)


def test_published_values_sit_beside_ours_and_are_labelled(project):
    table = _csv(project, "table1_methods")

    def published_row(rig, motion, method):
        rows = table[
            (table["rig"] == rig) & (table["motion"] == motion) & (table["method"] == method)
        ]
        return rows.iloc[0]

    row = published_row("quadruped", "Jumping & Playing", "nn")
    assert (row["published_joint_error"], row["published_fps"]) == ("0.087", "319.44")
    row = published_row("quadruped", "Average", "script")
    assert row["published_joint_error"] == "1.583" and row["published_total_time_s"] == "2.24"
    row = published_row("quadruped", "Begging Excitedly", "gpr_computed_jacobian")
    assert row["published_ground_truth_error"] == "0.56"  # printed digits kept
    tai_chi = published.table1_value("biped", "Tai Chi", "gpr_computed_jacobian")  # "Tai chi"
    assert tai_chi is not None and tai_chi.total_time_s == "85.71"
    assert published.table1_value("biped", "Average", "nn").total_time_s == "0.240"
    assert published_row("face", "Average", "nn")["published_joint_error"] == ""
    assert published_row("quadruped", "Average", "nn_learned_jacobian")["published_fps"] == ""
    assert len(published.TABLE1) == 48

    sampling = _csv(project, "table2_sampling")
    pca = sampling[(sampling["sampler"] == "pca_gaussian") & (sampling["rig"] == "face")]
    assert pca.iloc[0]["published_joint_error"] == "0.044"
    assert pca.iloc[0]["published_ground_truth_error"] == "1.482"
    rigs = _csv(project, "table3_rigs").set_index("rig")
    assert rigs.loc["quadruped", "published_rig_dofs"] == "642"
    assert published.TABLE3["biped"][2] == "697"
    assert rigs.loc["face", "published_character"] == "Facial"
    for name in ("table1_methods", "table2_sampling", "table3_rigs"):
        for suffix in ("md", "html"):
            text = (project["root"] / "reports" / "tables" / f"{name}.{suffix}").read_text()
            assert published.LABEL in text, (name, suffix)
    kernels = (project["root"] / "reports" / "tables" / "table_kernels.md").read_text()
    assert published.LABEL not in kernels  # the paper gives no kernel numbers


def test_sampling_and_kernel_tables_have_every_row(project):
    sampling = _csv(project, "table2_sampling")
    kernels = _csv(project, "table_kernels")
    for rig in RIGS:
        assert sampling[sampling["rig"] == rig]["sampler"].tolist() == list(SETTINGS.samplers)
        assert kernels[kernels["rig"] == rig]["kernel"].tolist() == list(SETTINGS.kernels)
    for table in (sampling, kernels):
        assert np.isfinite(table[["joint_error", "ground_truth_error"]].to_numpy(float)).all()
    expected = project["expected"][("face", "kernels", "linear")]
    row = kernels[(kernels["rig"] == "face") & (kernels["kernel"] == "linear")].iloc[0]
    assert math.isclose(row["joint_error"], expected.joint_error, rel_tol=1e-12)
    markdown = (project["root"] / "reports" / "tables" / "table2_sampling.md").read_text()
    for label in ("No Extra Samples", "Gaussian Mixture Model", "PCA & Unit Gaussian"):
        assert f"| {label} |" in markdown


def test_table3_counts_come_from_the_rigs_and_train_corpus(project):
    rigs = _csv(project, "table3_rigs").set_index("rig")
    for name in RIGS:
        rig = load(name)
        train = pd.read_parquet(project["root"] / "data" / name / "corpus" / "train.parquet")
        assert rigs.loc[name, "training_frames"] == len(train)
        assert rigs.loc[name, "rig_dofs"] == len(rig.control_names)
        assert rigs.loc[name, "used_rig_dofs"] == len(rig.used_controls)
        assert rigs.loc[name, "joint_dofs"] == 3 * rig.n_joints
        assert 0 < rigs.loc[name, "keyed_frames"] <= rigs.loc[name, "training_frames"]


# --------------------------------------------------------------------------- index and figures
class _Links(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        for key, value in attrs:
            if key in ("href", "src") and value and not value.startswith("#"):
                self.links.append(value)


def test_index_links_resolve_and_shows_tables_and_figures(project):
    index = project["files"].index
    text = index.read_text()
    parser = _Links()
    parser.feed(text)
    assert parser.links, "the index links nothing"
    for link in parser.links:
        assert (index.parent / link).is_file(), link
    for name in ("table1_methods", "table2_sampling", "table3_rigs", "table_kernels"):
        for suffix in ("md", "csv", "html"):
            assert f"tables/{name}.{suffix}" in parser.links
        assert f'id="{name}"' in text  # inline
    images = [link for link in parser.links if link.endswith(".png")]
    for rig in RIGS:
        assert f"figures/results/per_frame_{rig}.png" in images
    assert "figures/results/time_per_method.png" in images
    assert "figures/samples_quadruped.png" in images
    assert "samples sweep" in text or "supersamples" in text  # the skipped-figure note
    assert "Supersample grids (Fig. 4) not found for Face" in text
    assert "<script" not in text
    # latent synthesis (#18): its tables when latent_evaluate ran, said to be rigmap's own
    for name in ("table_latent_suites", "table_latent_matching"):
        assert f'id="{name}"' in text and f"tables/{name}.csv" in parser.links
    assert "table_latent_smoothness" not in text  # its CSV is absent: no table
    assert "rigmap&#x27;s own" in text or "rigmap's own" in text
    assert "figures/latent_face.png" in images
    suites = _csv(project, "table_latent_suites")
    assert suites["command"].tolist() == ["MOVE", "PLAY"] and suites["success_rate"][0] == 0.5
    assert set(suites["rig"]) == {"face"}
    matching = project["files"].tables["table_latent_matching"]["md"].read_text()
    assert "happy-roar" in matching and "—" in matching  # no pair found: no distance


def test_sweep_metrics_are_read_and_drawn(project, tmp_path):
    metrics = tmp_path / "metrics"
    shutil.copytree(project["root"] / "metrics", metrics)
    base = project["expected"][("face", "samplers", "pca_gaussian")]
    for n, scale in ((100, 3.0), (1000, 1.5), (10000, 1.0)):
        clips = [
            ClipResult(
                c.clip,
                c.joint_error_per_frame * scale,
                c.ground_truth_error_per_frame,
                c.total_time_s,
                frame_numbers=c.frame_numbers,
            )
            for c in base.clips
        ]
        result = MethodResult("face", "nn", "pca_gaussian", clips)
        result.write_json(metrics / "face" / "sample_sweep" / f"nn-pca_gaussian-{n}.json")
    tree = load_metrics(metrics, project["root"] / "data", SETTINGS)
    sweep = tree["face"].sweep["pca_gaussian"]
    assert list(sweep) == [100, 1000, 10000]
    assert sweep[100].average.joint_error == pytest.approx(3.0 * base.joint_error)
    assert tree["quadruped"].sweep == {}
    figure = sweep_figure(tree, tmp_path / "sweep.png")
    assert figure is not None and figure.path.stat().st_size > 1000


def test_the_joint_space_sweep_is_read_and_drawn_alone(project, tmp_path):
    metrics = tmp_path / "metrics"
    shutil.copytree(project["root"] / "metrics", metrics)
    base = project["expected"][("quadruped", "samplers", "pca_gaussian")]
    folder = metrics / "quadruped" / "sample_sweep_joint_space"
    for n, scale in ((600, 2.0), (6000, 1.0)):
        clips = [
            ClipResult(c.clip, c.joint_error_per_frame * scale, c.ground_truth_error_per_frame,
                       c.total_time_s, frame_numbers=c.frame_numbers)
            for c in base.clips
        ]  # fmt: skip
        result = MethodResult("quadruped", "nn_joint_space", "none", clips)
        result.write_json(folder / f"nn_joint_space-draws-{n}.json")
    tree = load_metrics(metrics, project["root"] / "data", SETTINGS)
    points = tree["quadruped"].joint_space_sweep
    assert list(points) == [600, 6000]
    assert points[600].average.joint_error == pytest.approx(2.0 * base.joint_error)
    assert tree["quadruped"].sweep == {} and tree["face"].joint_space_sweep == {}
    figure = sweep_figure(tree, tmp_path / "sweep.png")  # no control-space sweep: drawn alone
    assert figure is not None and figure.path.stat().st_size > 1000
    (folder / "stray.json").write_text("{}")
    with pytest.raises(ReportInputError, match=r"nn_joint_space-draws-<draws>\.json"):
        load_metrics(metrics, project["root"] / "data", SETTINGS)


# --------------------------------------------------------------------------- bad input
def test_missing_files_are_listed_by_name(project, tmp_path):
    metrics = tmp_path / "metrics"
    shutil.copytree(project["root"] / "metrics", metrics)
    (metrics / "quadruped" / "samplers" / "nn-gmm.json").unlink()
    (metrics / "face" / "per_frame" / "methods" / "gpr-none.csv").unlink()
    with pytest.raises(ReportInputError) as error:
        build_report(
            metrics_root=metrics,
            data_root=project["root"] / "data",
            reports_root=tmp_path / "reports",
            settings=SETTINGS,
        )
    message = str(error.value)
    assert str(metrics / "quadruped" / "samplers" / "nn-gmm.json") in message
    assert str(metrics / "face" / "per_frame" / "methods" / "gpr-none.csv") in message
    assert "2 metrics file(s) missing" in message
    assert not (tmp_path / "reports").exists()  # nothing written


def test_bad_files_are_named_with_what_was_expected(project, tmp_path):
    metrics = tmp_path / "metrics"
    shutil.copytree(project["root"] / "metrics", metrics)
    data = project["root"] / "data"
    path = metrics / "quadruped" / "kernels" / "gpr-linear.json"

    def fails_with(*fragments):
        with pytest.raises(ReportInputError) as error:
            load_metrics(metrics, data, SETTINGS)
        for fragment in (str(path), *fragments):
            assert fragment in str(error.value)

    original = path.read_text()
    path.write_text(original[:40])
    fails_with("not a readable JSON")
    content = json.loads(original)
    path.write_text(json.dumps({**content, "rig": "biped"}))
    fails_with("field 'rig' is 'biped'", "'quadruped'")
    clips = dict(content["clips"])
    clips.pop(next(iter(clips)))
    path.write_text(json.dumps({**content, "clips": clips}))
    fails_with("expected the test clips", "missing ['Jumping & Playing']")
    path.write_text(json.dumps({**content, "average": {**content["average"], "fps": None}}))
    fails_with("expected a number for 'fps'")
    path.write_text(original)
    csv = metrics / "quadruped" / "per_frame" / "methods" / "nn-pca_gaussian.csv"
    frame = pd.read_csv(csv)
    frame.loc[0, "joint_error"] += 1.0
    frame.to_csv(csv, index=False)
    tree = load_metrics(metrics, data, SETTINGS)
    with pytest.raises(ReportInputError, match=r"disagrees with nn-pca_gaussian\.json"):
        tree["quadruped"].methods["nn"].per_frame()


def test_table1_covers_only_the_method_rigs(project):
    settings = ReportSettings(rigs=RIGS, method_rigs=("quadruped",))
    tree = load_metrics(project["root"] / "metrics", project["root"] / "data", settings)
    assert tree["face"].methods == {} and len(tree["face"].samplers) == 6
    table = methods_table(tree, settings)
    assert set(table.data["rig"]) == {"quadruped"}
    note = "compared on Quadruped; Face appears in Table 2, Table 3 and the kernel table."
    assert any(note in n for n in table.notes), table.notes
    # a rig outside the per-rig tables appears in Table 3 only, and the note says so
    only_table3 = ReportSettings(rigs=RIGS, method_rigs=("quadruped",), sampler_rigs=("quadruped",))
    notes = methods_table(tree, only_table3).notes
    assert any("compared on Quadruped; Face appears in Table 3." in n for n in notes), notes
    with pytest.raises(
        ValueError, match=r"method_rigs \['biped', 'squirrel', 'rigify_wolf'\] are not among"
    ):
        ReportSettings(rigs=RIGS)
    with pytest.raises(ValueError, match=r"sampler_rigs \['biped'\] are not among rigs"):
        ReportSettings(rigs=RIGS, method_rigs=RIGS, sampler_rigs=("biped",))


def test_a_methods_only_rig_with_a_frame_budget_is_labelled(project, tmp_path):
    """A rig evaluated on the first frames of its clips (the Blender wolf's quick budget)."""
    root = tmp_path / "copy"
    shutil.copytree(project["root"] / "metrics", root / "metrics")
    shutil.copytree(project["root"] / "data", root / "data")
    for folder in ("samplers", "kernels"):  # face runs Table 1 only
        shutil.rmtree(root / "metrics" / "face" / folder)
    for path in (root / "metrics" / "face" / "methods").glob("*.json"):
        data = json.loads(path.read_text())
        data["extra"]["frames_per_clip"] = 2
        data["extra"]["budget"] = {"gpr_points": 40}
        path.write_text(json.dumps(data))
    settings = ReportSettings(rigs=RIGS, method_rigs=RIGS, sampler_rigs=("quadruped",))
    tree = load_metrics(root / "metrics", root / "data", settings)
    assert tree["face"].samplers == {} and tree["face"].kernels == {}
    table = methods_table(tree, settings)
    face = table.data[table.data["rig"] == "face"]
    assert set(face["frames_per_clip"]) == {2}
    assert table.data[table.data["rig"] == "quadruped"]["frames_per_clip"].isna().all()
    labels = [row[0] for row in table.rows if row[0].startswith("Face")]
    assert labels and all(label.endswith("(first 2 frames)") for label in labels)
    budget = [n for n in table.notes if n.startswith("Face: every method is scored on the first 2")]
    assert len(budget) == 1 and budget[0].endswith(
        "Its GPR keeps 40 support points (budget.gpr_points)."
    )
    assert [n for n in table.notes if n.startswith("Budget of Face")] == [
        "Budget of Face (from the metrics files): the first 2 frames of a clip; GPR of 40 "
        "support points."
    ]  # the run's budget, as each rig's metrics files recorded it
    assert set(sampling_table(tree, settings).data["rig"]) == {"quadruped"}
    assert set(kernels_table(tree, settings).data["rig"]) == {"quadruped"}
    # one rig's rows scored on different frames would not compare: refused, naming the rig
    path = root / "metrics" / "face" / "methods" / "gpr-none.json"
    data = json.loads(path.read_text())
    data["extra"]["frames_per_clip"] = None
    path.write_text(json.dumps(data))
    tree = load_metrics(root / "metrics", root / "data", settings)
    with pytest.raises(ReportInputError, match="rig 'face': the Table 1 metrics files were scored"):
        methods_table(tree, settings)


def test_table3_says_what_a_blender_rig_counts():
    facts = [
        RigFacts("quadruped", 884, 200, 769, 218, 228, "cm"),
        RigFacts("rigify_wolf", 891, 303, 2301, 161, 195, "cm", backend="blender"),
    ]
    table = rigs_table(facts)
    assert [row[0] for row in table.rows] == ["Quadruped", "Rigify Wolf (Blender)"]
    assert table.rows[1][1:6] == ["891", "303", "2301", "161", "195"]
    assert list(table.data["backend"]) == ["built-in", "blender"]
    assert any(n.startswith("Rigify Wolf (Blender): Blender rigs") for n in table.notes)


def test_settings_label_an_uncatalogued_row_by_its_name_and_refuse_unknown_keys():
    settings = ReportSettings(methods=("nn", "nn_magic"), samplers=("none", "jitter"))
    assert settings.catalogue.method("nn_magic").display == "nn_magic"  # no KeyError
    assert settings.catalogue.sampler("jitter").label == "jitter"
    assert settings.catalogue.method("nn").label == "NN"
    with pytest.raises(ValueError, match="unknown keys \\['colour'\\]"):
        ReportSettings.from_mapping({"colour": "red"})
    settings = ReportSettings.from_mapping(
        {"rigs": ["face"], "method_rigs": ["face"], "nn_sampler": "uniform"}
    )
    assert settings.method_sampler("nn_learned_jacobian") == "uniform"
    assert settings.method_sampler("gpr_computed_jacobian") == "none"
    # the guess's regressor decides (rigmap.catalog), as the evaluate stage names its files
    assert settings.method_sampler("nn_joint_space_tuned") == "none"
    assert settings.method_sampler("nn_autodiff_jacobian") == "uniform"
    assert "script" not in settings.methods_for("face")


def test_report_stage_reads_rows_from_the_evaluate_config():
    from hydra import compose, initialize_config_dir

    sys.path.insert(0, str(ROOT / "pipelines"))
    try:
        import report as report_stage
    finally:
        sys.path.remove(str(ROOT / "pipelines"))
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=["sampler=gmm"])
    settings = report_stage.report_settings(cfg)
    assert settings.nn_sampler == "gmm"
    assert settings.rigs == (
        "quadruped", "biped", "face", "squirrel", "rigify_wolf", "blend_file:hero"
    )  # fmt: skip
    # the evaluate stages: the matrix, the mesh rigs' family (issue #42), the Blender wolf's own
    # (Table 1 only, no autodiff), and the user's .blend the Blender families run
    # (blend_file:<stem> in pipeline.blender_rigs)
    assert settings.method_rigs == (
        "quadruped", "biped", "face", "squirrel", "rigify_wolf", "blend_file:hero"
    )  # fmt: skip
    for mesh in ("face", "squirrel"):  # evaluate_mesh: their rig configs' _overrides_ methods
        assert settings.methods_for(mesh) == (
            "gpr", "gpr_learned_jacobian", "gpr_computed_jacobian", "nn", "nn_computed_jacobian",
            "nn_learned_jacobian", "nn_autodiff_jacobian", "mean",
        )  # fmt: skip
    assert settings.methods_for("blend_file:hero") == (
        "gpr", "gpr_learned_jacobian", "gpr_computed_jacobian", "nn", "nn_computed_jacobian",
        "nn_learned_jacobian", "mean",
    )  # fmt: skip
    # the sweeps: experiment=quick's two rigs, the paper's four
    assert settings.sampler_rigs == ("quadruped", "biped")
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        paper = compose(config_name="config", overrides=["experiment=paper"])
    assert report_stage.report_settings(paper).sampler_rigs == (
        "quadruped",
        "biped",
        "face",
        "squirrel",
    )
    assert "nn_autodiff_jacobian" not in settings.methods_for("rigify_wolf")
    assert "nn_joint_space" not in settings.methods_for("rigify_wolf")  # needs gradients
    assert "script" in settings.methods_for("rigify_wolf")


# --------------------------------------------------------------------------- reproduce
def _mini_project(folder: Path, *, dvc_init: bool = False) -> Path:
    """conf/ of the repository and a two-stage dvc.yaml that reads params.yaml."""
    folder = folder / "project"
    shutil.copytree(ROOT / "conf", folder / "conf")
    (folder / "dvc.yaml").write_text(
        "stages:\n"
        "  samples:\n"
        "    cmd: python -c \"open('n.txt','w').write('${budget.samples}')\"\n"
        "    outs: [n.txt]\n"
        "  report:\n"
        "    cmd: python -c \"import os; os.makedirs('reports', exist_ok=True); "
        "open('reports/index.html','w').write(open('n.txt').read())\"\n"
        "    deps: [n.txt]\n"
        "    outs: [reports/index.html]\n"
    )
    if dvc_init:
        dvc = Path(sys.executable).parent / "dvc"
        subprocess.run([str(dvc), "init", "--no-scm", "-q"], cwd=folder, check=True)
    return folder


def test_reproduce_arguments_are_checked(tmp_path):
    from rigmap.app.params import ParamsError
    from rigmap.reproduce import plan_reproduce

    project = _mini_project(tmp_path)
    with pytest.raises(ParamsError, match=r"unknown experiment 'huge'.*'paper', 'quick'"):
        plan_reproduce(["experiment=huge"], project=project)
    with pytest.raises(ParamsError, match="expected KEY=VALUE"):
        plan_reproduce(["paper"], project=project)
    with pytest.raises(ParamsError, match="expected a stage name"):
        plan_reproduce([], targets=["budget.samples=3"], project=project)
    with pytest.raises(ParamsError, match="no project found"):
        plan_reproduce([], project=tmp_path)  # holds the project, is none
    plan = plan_reproduce(
        ["experiment=paper"], targets=["report"], project=project, dry=True, force=True
    )
    assert plan.command[1:] == ("repro", "report", "--dry", "--force")
    assert plan.bin_dir == str(Path(sys.executable).parent)
    assert plan.env["PATH"].startswith(str(Path(sys.executable).parent))
    assert not plan.count_stages


def test_reproduce_cli_rejects_bad_overrides(capsys, tmp_path):
    from rigmap.cli import main

    project = _mini_project(tmp_path)
    code = main(["reproduce", "experiment=huge", "--project", str(project)])
    assert code == 2
    assert "unknown experiment 'huge'" in capsys.readouterr().err
    assert not (project / "params.yaml").exists()


def test_reproduce_runs_dvc_with_the_composed_experiment(tmp_path):
    import io

    from rigmap.reproduce import plan_reproduce, run_reproduce

    project = _mini_project(tmp_path, dvc_init=True)
    out = io.StringIO()
    code = run_reproduce(plan_reproduce(["experiment=paper"], project=project), out=out)
    text = out.getvalue()
    assert code == 0, text
    assert (project / "n.txt").read_text() == "100000"  # experiment=paper's budget.samples
    assert "params.yaml updated: experiment=paper" in text
    assert "[rigmap reproduce] 2 stage(s) changed or downstream of a change" in text
    assert "[rigmap reproduce] stage 1/2: samples" in text
    assert re.search(r"\[rigmap reproduce\] stage 2/2: report \(previous took \d+\.\d s\)", text)
    assert "[rigmap reproduce] 2 stage(s) ran in" in text
    summary = text[text.index("by stage family:") :]
    assert "  samples (1)" in summary and "  report (1)" in summary
    assert f"report: {project / 'reports' / 'index.html'}" in text
    import yaml

    assert yaml.safe_load((project / "params.yaml").read_text())["budget"]["samples"] == 100000


def test_params_yaml_is_what_dvc_exp_run_writes(tmp_path):
    from dvc.utils.hydra import compose_and_dump

    from rigmap.app.params import reaching_stages, write_params

    project = _mini_project(tmp_path)
    overrides = ["experiment=paper", "regressor.hidden=1024"]
    update = write_params(project, overrides)
    compose_and_dump(tmp_path / "dvc.yaml", str(project / "conf"), None, "config", "", overrides)
    assert update.path.read_text() == (tmp_path / "dvc.yaml").read_text()  # byte for byte
    assert update.params["regressor"]["hidden"] == 1024
    assert update.params["budget"]["hidden"] == 2048  # the paper's; the override wins
    assert "regressor.hidden" in update.differs_from_defaults
    assert not write_params(project, overrides).changed  # same experiment: file untouched
    # the mini pipeline interpolates ${budget.samples} only
    assert reaching_stages(["budget.samples", "regressor.hidden"], project / "dvc.yaml") == [
        "budget.samples"
    ]
    assert reaching_stages(["regressor.alpha"], project / "dvc.yaml") == []


def test_reproduce_params_only_writes_params_and_runs_nothing(tmp_path, capsys):
    from rigmap.cli import main

    project = _mini_project(tmp_path)
    code = main(["reproduce", "seed=3", "--params-only", "--project", str(project)])
    output = capsys.readouterr().out
    assert code == 0
    assert "differs from the defaults: regressor.seed, seed" in output
    assert "warning: no stage in dvc.yaml interpolates any of these values" in output
    assert "seed: 3" in (project / "params.yaml").read_text()
    assert not (project / "n.txt").exists()


def test_a_users_blend_file_must_be_named_after_the_file():
    with pytest.raises(ValueError, match="blend_file:<file stem>"):
        ReportSettings(blend_file_rigs=("hero",))
    settings = ReportSettings(blend_file_rigs=("blend_file:hero",))
    assert settings.rigs[-1] == "blend_file:hero" and "script" not in settings.methods_for(
        "blend_file:hero"
    )
