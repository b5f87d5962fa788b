"""The report the pipeline wrote (``reports/`` of this checkout): every row there, numbers sane.

``make test`` checks the report in the checkout: the committed one, or in CI the one
``make reproduce`` has just rebuilt from nothing (``.ci/run`` runs it first). Only the
structure and sanity are checked — every method, sampler, kernel and rig row the report
stage was configured for, finite non-negative numbers, the figures and index — not the
values, which are what the experiment measured.
"""

from __future__ import annotations

import math
import re
import shlex
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from rigmap.animation.library import libraries, motion_library
from rigmap.store.pipeline_files import stage_families

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"
TABLES = REPORTS / "tables"
MEASURED = ("joint_error", "ground_truth_error", "total_time_s", "fps")

pytestmark = pytest.mark.skipif(
    not (REPORTS / "index.html").is_file(), reason="no report in this checkout (run make reproduce)"
)


@pytest.fixture(scope="module")
def settings():
    """The rows the report stage expects, composed exactly as ``dvc.yaml``'s report stage does."""
    from hydra import compose, initialize_config_dir

    stage = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]["report"]
    words = shlex.split(stage["cmd"])
    overrides = words[words.index("pipelines/report.py") + 1 :]
    sys.path.insert(0, str(ROOT / "pipelines"))
    try:
        import report as report_stage
    finally:
        sys.path.remove(str(ROOT / "pipelines"))
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = compose(config_name="config", overrides=overrides)
    return report_stage.report_settings(cfg)


def read_table(name: str) -> pd.DataFrame:
    path = TABLES / f"{name}.csv"
    assert path.is_file(), f"{path} is missing"
    for suffix in (".md", ".html"):
        assert path.with_suffix(suffix).is_file(), f"{path.with_suffix(suffix)} is missing"
    return pd.read_csv(path)


def assert_sane(table: pd.DataFrame, name: str) -> None:
    for column in MEASURED:
        if column not in table:
            continue
        values = table[column].astype(float)
        bad = table[~values.map(math.isfinite) | (values < 0)]
        assert bad.empty, f"{name}: {column} not finite and >= 0 in rows\n{bad}"
    if "fps" in table:
        assert (table["fps"] > 0).all(), f"{name}: a row has fps 0"
    if "frames" in table:
        assert (table["frames"] > 0).all(), f"{name}: a row scored no frame"


def clips_of(rig: str) -> tuple[str, ...]:
    """A built-in rig's test clips from its motion library; a user's .blend (``blend_file:``)
    has none: its test clips are the actions its corpus import put in the test split."""
    if rig.startswith("blend_file:"):
        corpus = ROOT / "data" / rig / "corpus" / "test.parquet"
        return tuple(dict.fromkeys(pd.read_parquet(corpus, columns=["clip"])["clip"].astype(str)))
    assert rig in libraries(), f"{rig} has no motion library to name its test clips"
    return tuple(m.name for m in motion_library(rig).test)


def test_table1_has_every_method_on_every_test_clip_and_the_average(settings):
    table = read_table("table1_methods")
    assert_sane(table, "table1_methods")
    for rig in settings.method_rigs:
        clips = settings.clips or clips_of(rig)
        methods = [m for m in settings.methods if m not in settings.excluded_methods.get(rig, ())]
        rows = table[table["rig"] == rig]
        for motion in (*clips, "Average"):
            found = sorted(rows.loc[rows["motion"] == motion, "method"])
            assert found == sorted(methods), f"table1 {rig} / {motion}: methods {found}"
    assert set(table["rig"]) == set(settings.method_rigs)


@pytest.mark.parametrize(
    ("name", "column", "expected"),
    [("table2_sampling", "sampler", "samplers"), ("table_kernels", "kernel", "kernels")],
)
def test_sampling_and_kernel_tables_have_a_row_per_rig_and_choice(settings, name, column, expected):
    table = read_table(name)
    assert_sane(table, name)
    for rig in settings.sampler_rigs:
        found = sorted(table.loc[table["rig"] == rig, column])
        assert found == sorted(getattr(settings, expected)), f"{name} {rig}: {found}"
    assert set(table["rig"]) == set(settings.sampler_rigs)


def test_table3_counts_every_rig(settings):
    table = read_table("table3_rigs")
    assert sorted(table["rig"]) == sorted(settings.rigs)
    for column in ("training_frames", "rig_dofs", "used_rig_dofs", "joint_dofs"):
        assert (table[column] > 0).all(), f"table3: {column} has a non-positive count"
    assert (table["used_rig_dofs"] <= table["rig_dofs"]).all()


def test_index_links_resolve_and_figures_are_drawn():
    html = (REPORTS / "index.html").read_text("utf-8")
    links = re.findall(r'(?:href|src)="([^"#:]+)"', html)
    assert links, "index.html links nothing"
    missing = [link for link in links if not (REPORTS / link).is_file()]
    assert not missing, f"index.html links missing files: {missing}"
    figures = sorted((REPORTS / "figures" / "results").glob("*.png"))
    assert figures, "no result figures in reports/figures/results"
    assert all(path.stat().st_size > 1000 for path in figures)
    if "sample_sweep" in stage_families(ROOT):  # drawn as error against supersamples
        names = {path.name for path in figures}
        assert "joint_error_vs_supersamples.png" in names, f"figures drawn: {sorted(names)}"
