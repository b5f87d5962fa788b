"""The latent stages (pipelines/latent.py) and ``rigmap synth`` on a tiny face config.

Two labels of the face's quick library, small fits (4 PCA components, 2 latent
dimensions, 25 L-BFGS iterations: a test-sized config, ours); every step computes for
real and the assertions are on its numbers and files.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from rigmap.app.latent import run_step, step_metrics
from rigmap.cli import main
from rigmap.latent import steps
from rigmap.latent.errors import LatentInputError
from rigmap.reports.latent_tables import latent_figures, latent_tables
from rigmap.rigs import load
from rigmap.store import Layout

ROOT = Path(__file__).resolve().parents[1]
TINY = [
    "rig=face",
    "latent.labels=[happy,neutral]",
    "latent.n_pca=4",
    "latent.latent_dim=2",
    "latent.max_iter=25",
    "latent.match_max_iter=30",
    "latent.match_threshold_cm=0.5",
    "latent.log_to_mlflow=false",
    "latent.seeds=[0,1]",
    "latent.evaluate.pca_sizes=[1,3]",
    "latent.evaluate.latent_dims=[1,2]",
    "latent.evaluate.compare_dims=[2]",
    "latent.evaluate.compare_labels=2",
    "latent.evaluate.sweep_labels=1",
    "latent.evaluate.transition_starts=1",
    "latent.evaluate.smoothness_pairs=1",
    "latent.evaluate.suite_commands=2",
]
SCRIPT = """start: happy
commands:
  - move: {take: happy 1, frame: 10}
  - idle: {frames: 12}
  - transition: {model: neutral}
  - play: {take: neutral 0}
"""


def compose(tmp: Path, *extra: str):
    from rigmap.cli import compose_config

    paths = [f"paths.{k}={tmp / k}" for k in ("data", "models", "metrics", "reports")]
    return compose_config([*TINY, *paths, *extra], ROOT / "conf")


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """fit and match once, with a script of the two labels (the stage code in-process)."""
    tmp = tmp_path_factory.mktemp("latent")
    script = tmp / "two_labels.yaml"
    script.write_text(SCRIPT)
    for step in ("fit", "match"):
        run_step(compose(tmp, f"+latent_step={step}"))
    return tmp, script


def layout(tmp: Path) -> Layout:
    return Layout.from_paths({k: str(tmp / k) for k in ("data", "models", "metrics", "reports")})


def test_fit_writes_a_model_per_label_at_the_configured_sizes(project):
    tmp, _ = project
    info = json.loads((tmp / "models/face/latent/fit/fit.json").read_text())
    assert sorted(info) == ["happy", "neutral"]
    fitted = steps.load_fitted(layout(tmp), "face")
    for label, record in info.items():
        assert record["pca_dims"] == 4 and record["latent_dim"] == 2
        assert record["frames"] == fitted.sets[label].n_frames > 100
        assert record["objective_end"] < record["objective_start"]  # the fit did descend
        assert fitted.models[label].latent.shape == (record["frames"], 2)


def test_match_finds_bridges_whose_poses_are_within_the_threshold(project):
    tmp, _ = project
    record = json.loads((tmp / "models/face/latent/match/match.json").read_text())
    assert record["threshold_cm"] == 0.5
    (pair,) = record["pairs"]
    assert pair["pair"] == "happy-neutral" and pair["points"] > 0
    assert 0 <= pair["distance_cm_median"] <= pair["distance_cm_max"] < 0.5
    table = steps.load_table(layout(tmp), "face")
    assert table.route("happy", "neutral") == ["happy", "neutral"]


def test_synthesize_plays_each_script_per_seed_into_controls_parquet(project):
    tmp, script = project
    run_step(compose(tmp, "+latent_step=synthesize", f"latent.scripts=[{script}]"))
    folder = tmp / "data/face/latent"
    rig = load("face")
    runs_ = [pd.read_parquet(folder / f"two_labels-seed{s}.parquet") for s in (0, 1)]
    for table in runs_:
        assert list(table.columns) == ["frame", *rig.used_controls]
        assert len(table) > 12 + 24 and np.isfinite(table.to_numpy()).all()
    log = json.loads((folder / "log.json").read_text())
    commands = [row["command"] for row in log["two_labels-seed0"]]
    assert commands == ["MOVE", "IDLE", "TRANSITION", "PLAY"]
    assert all(row["success"] for row in log["two_labels-seed0"])
    n = min(len(t) for t in runs_)
    differ = np.abs(runs_[0].to_numpy()[:n, 1:] - runs_[1].to_numpy()[:n, 1:]).max()
    assert 0 < differ < 1.0  # another seed's random force: a little different, same shot


def test_evaluate_writes_every_measurement_and_fig_2(project):
    tmp, script = project
    run_step(compose(tmp, "+latent_step=evaluate", f"latent.scripts=[{script}]"))
    folder = tmp / "metrics/face/latent"
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["metrics_are_rigmaps_own"] is True
    assert set(summary["pca_dims_at_85"]) == {"happy", "neutral"}
    assert all(1 <= d <= 4 for d in summary["pca_dims_at_85"].values())
    assert set(summary["heldout_surface_rms_cm_by_latent_dim"]) == {"1", "2"}
    assert all(0 < v < 1 for v in summary["heldout_surface_rms_cm_by_latent_dim"].values())
    scaling = pd.read_csv(folder / "scaling.csv")
    assert list(scaling["pca_dims"]) == [1, 3]
    assert (scaling["scaled_surface_rms_cm"].diff().dropna() < 0).all()  # more dims, less error
    one = pd.read_csv(folder / "one_vs_per_label.csv")
    assert set(one["models"]) == {"one for all", "one per label"}
    suites = pd.read_csv(folder / "suites.csv")
    assert list(suites["command"]) == ["MOVE", "IDLE", "TRANSITION", "PLAY"]
    # every command of the tiny suite completes, within the frames its script allows
    assert (suites["success_rate"] >= 0.9).all() and (suites["count"] == 2).all(), suites
    assert (suites["frames_median"] <= suites["frames_max"]).all()
    smooth = pd.read_csv(folder / "smoothness.csv")
    assert len(smooth) == 1
    # the paper's comparison (Bailey et al. §6): latent transitions smoother than motion-graph
    # blends, and able to start from more of the data
    row = smooth.iloc[0]
    assert row["ours_peak_acc_rel_p95"] < row["graph_peak_acc_rel_p95"]
    assert row["ours_peak_jerk_rel_p95"] < row["graph_peak_jerk_rel_p95"]
    assert row["ours_start_fraction"] > row["graph_start_fraction"]
    repeats = summary["seed_repeats"]["two_labels"]
    assert repeats["runs"] == 2 and 0 < repeats["pairwise_rms_cm_min"] < 1.0
    assert (tmp / "reports/figures/latent_face.png").stat().st_size > 10_000
    metrics = step_metrics("evaluate", summary, 1.0)
    by_dim = summary["heldout_surface_rms_cm_by_latent_dim"]
    assert metrics["heldout_surface_rms_cm.q2"] == by_dim["2"]
    # the report's tables and Fig 2, which say the metrics are rigmap's own
    tables = {t.name: t for t in latent_tables(tmp / "metrics")}
    assert len(tables) == 7 and all("rigmap's own" in t.notes[0] for t in tables.values())
    assert [row[1] for row in tables["table_latent_suites"].rows] == list(suites["command"])
    (figure,) = latent_figures(tmp / "reports/figures")
    assert figure.path.name == "latent_face.png" and "connectivity prior" in figure.caption


def test_synth_run_writes_controls_and_names_bad_commands(project, tmp_path, capsys):
    tmp, script = project
    paths = [f"paths.{k}={tmp / k}" for k in ("data", "models", "metrics", "reports")]
    out = tmp_path / "shot.parquet"
    options = ["--out", str(out), "--seed", "3", "--config-dir", str(ROOT / "conf")]
    assert main(["synth", "run", str(script), *TINY, *paths, *options]) == 0
    table = pd.read_parquet(out)
    assert table["frame"].tolist() == list(range(len(table))) and len(table) > 36
    printed = capsys.readouterr()
    assert "TRANSITION" in printed.out
    assert "synthesis" in printed.err  # the progress bar of the frames played, on stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("start: happy\ncommands:\n  - transition: {model: sleepy}\n")
    assert main(["synth", "run", str(bad), *TINY, *paths, *options]) == 2
    assert "unknown model 'sleepy'" in capsys.readouterr().err
    bad.write_text("start: happy\ncommands:\n  - play: {take: roar 0}\n")
    assert main(["synth", "run", str(bad), *TINY, *paths, *options]) == 2
    assert "unknown segment 'roar 0' in model 'happy'" in capsys.readouterr().err
    out.unlink()
    bad.write_text("start: happy\ncommands:\n  - idle: {frames: 10000000}\n")
    assert main(["synth", "run", str(bad), *TINY, *paths, *options]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: command 1 (idle frames=10000000) passes the cap" in err
    assert "accepted: 0 to 100000 frames in all" in err and "synthesis" not in err
    assert not out.exists()  # refused before anything played or was written


def test_synth_demo_plays_a_game_through_the_controller(project, tmp_path, capsys):
    tmp, _ = project
    paths = [f"paths.{k}={tmp / k}" for k in ("data", "models", "metrics", "reports")]
    out = tmp_path / "demo.parquet"
    options = ["--seed", "1", "--frames-per-turn", "6", "--out", str(out)]
    assert main(["synth", "demo", *TINY, *paths, *options, "--config-dir", str(ROOT / "conf")]) == 0
    printed = capsys.readouterr().out
    assert "game 1:" in printed and "frames/s" in printed
    assert ("win" in printed) or ("loss" in printed) or ("draw" in printed)
    assert len(pd.read_parquet(out)) >= 5 * 6


def test_missing_models_and_bad_steps_are_clear_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="run the latent fit step first"):
        steps.load_fitted(layout(tmp_path), "face")
    with pytest.raises(LatentInputError, match=r"\+latent_step: expected one of"):
        run_step(compose(tmp_path, "+latent_step=bake"))
    with pytest.raises(LatentInputError, match="no command script 'nope'"):
        steps.script_path("nope")
    with pytest.raises(LatentInputError, match="no labelled sets"):
        steps.sets_of(OmegaConf.to_container(compose(tmp_path).latent), load("biped"))


def test_the_stage_script_reports_a_bad_step_as_one_line(tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            str(ROOT / "pipelines/latent.py"),
            "rig=face",
            "+latent_step=bake",
            f"paths.models={tmp_path}",
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert result.returncode == 2
    assert "error: latent:" in result.stderr and "+latent_step" in result.stderr


def test_synth_help_names_the_verbs(capsys):
    with pytest.raises(SystemExit):
        main(["synth", "--help"])
    text = capsys.readouterr().out
    for verb in ("fit", "match", "run", "demo"):
        assert verb in text
    with pytest.raises(SystemExit):
        main(["synth", "run", "--help"])
    assert "command script" in capsys.readouterr().out


def test_the_evaluate_run_in_mlflow_carries_every_steps_numbers(project, tmp_path):
    """latent.mlflow_steps=[evaluate] (quick): one run with fit, match and synthesize too."""
    from mlflow import MlflowClient

    from rigmap.app.latent import latent_config, log_step

    tmp, script = project
    summary = tmp / "metrics/face/latent/summary.json"
    if not summary.is_file():  # run alone: the steps before it first
        for step in ("synthesize", "evaluate"):
            run_step(compose(tmp, f"+latent_step={step}", f"latent.scripts=[{script}]"))
    uri = f"sqlite:///{tmp_path / 'mlruns.db'}"
    cfg = compose(tmp, "latent.log_to_mlflow=true", f"tracking.uri={uri}")
    run_id = log_step(cfg, "face", "evaluate", latent_config(cfg), summary, 2.5, layout=layout(tmp))
    run = MlflowClient(uri).get_run(run_id)
    assert run.data.tags["stage"] == "latent_evaluate" and run.info.run_name == "latent-evaluate"
    metrics = run.data.metrics
    record = json.loads(summary.read_text())
    assert metrics["seconds"] == 2.5
    assert (
        metrics["heldout_surface_rms_cm.q1"] == record["heldout_surface_rms_cm_by_latent_dim"]["1"]
    )
    assert metrics["fit.happy.pca_dims"] == 4 and metrics["match.points.happy-neutral"] > 0
    assert "synthesize.two_labels-seed0.frames" in metrics and "fit.seconds" not in metrics
    files = {f.path for f in MlflowClient(uri).list_artifacts(run_id, "fit")}
    assert files == {"fit/fit.json"}
