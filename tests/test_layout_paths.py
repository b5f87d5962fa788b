"""Every kind of path ``Layout`` owns is the same string as before it owned it (issue #35).

The expected strings were written from the code that built each path itself (edits,
latent, map, reports, tracking, the user's outputs and caches) before those callers asked
``Layout``: the DVC pipeline's outs name them, so none may move. A second test reads
``src/rigmap`` for path literals and ``__file__`` outside ``store/layout.py``; the few that
stay are listed with their reason.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rigmap.store.layout import Layout, ModelId, packaged_conf

SRC = Path(__file__).resolve().parents[1] / "src" / "rigmap"
RIG = "quadruped"
GPR = ModelId("gpr", "none", "multiquadric")
NN = ModelId("nn", "pca_gaussian")

# (kind, call on Layout(), today's path) — seed 0, the committed run
EXPECTED = [
    ("rig_data", lambda lay: lay.rig_data(RIG), "data/quadruped"),
    ("corpus train", lambda lay: lay.corpus(RIG, "train"), "data/quadruped/corpus/train.parquet"),
    ("corpus test", lambda lay: lay.corpus(RIG, "test"), "data/quadruped/corpus/test.parquet"),
    (
        "corpus heldout",
        lambda lay: lay.corpus(RIG, "heldout"),
        "data/quadruped/heldout/corpus.parquet",
    ),
    ("corpus_folder", lambda lay: lay.corpus_folder(RIG), "data/quadruped/corpus"),
    ("poses test", lambda lay: lay.poses(RIG, "test"), "data/quadruped/poses/test.parquet"),
    (
        "poses heldout",
        lambda lay: lay.poses(RIG, "heldout"),
        "data/quadruped/heldout/poses.parquet",
    ),
    ("poses_folder", lambda lay: lay.poses_folder(RIG), "data/quadruped/poses"),
    (
        "samples",
        lambda lay: lay.samples(RIG, "pca_gaussian"),
        "data/quadruped/samples/pca_gaussian.npz",
    ),
    ("rig_models", lambda lay: lay.rig_models(RIG), "models/quadruped"),
    ("model", lambda lay: lay.model(RIG, GPR), "models/quadruped/gpr-none-multiquadric"),
    ("metrics_folder", lambda lay: lay.metrics_folder(RIG, "methods"), "metrics/quadruped/methods"),
    # the evaluate sets' files the report reads (reports/metrics_tree.py)
    (
        "metrics_file methods",
        lambda lay: lay.metrics_file(RIG, "methods", "nn-pca_gaussian"),
        "metrics/quadruped/methods/nn-pca_gaussian.json",
    ),
    (
        "metrics_file kernels",
        lambda lay: lay.metrics_file(RIG, "kernels", "gpr-multiquadric"),
        "metrics/quadruped/kernels/gpr-multiquadric.json",
    ),
    # edits (edits/steps.py)
    ("app_data edits", lambda lay: lay.app_data(RIG, "edits"), "data/quadruped/edits"),
    ("app_models edits", lambda lay: lay.app_models(RIG, "edits"), "models/quadruped/edits"),
    ("app_metrics edits", lambda lay: lay.app_metrics(RIG, "edits"), "metrics/quadruped/edits"),
    (
        "edits_refinement",
        lambda lay: lay.edits_refinement(RIG),
        "metrics/quadruped/edits/refinement",
    ),
    # latent (latent/steps.py fit_folder, match_folder; app/latent.py's log)
    ("app_data latent", lambda lay: lay.app_data(RIG, "latent"), "data/quadruped/latent"),
    ("app_models latent", lambda lay: lay.app_models(RIG, "latent"), "models/quadruped/latent"),
    ("app_metrics latent", lambda lay: lay.app_metrics(RIG, "latent"), "metrics/quadruped/latent"),
    ("latent_fit", lambda lay: lay.latent_fit(RIG), "models/quadruped/latent/fit"),
    ("latent_match", lambda lay: lay.latent_match(RIG), "models/quadruped/latent/match"),
    # map (map/subset_model.py's cache, app/map_stage.py, app/map_suite.py)
    ("map_model", lambda lay: lay.map_model(RIG, "legs"), "models/quadruped/map-legs"),
    ("map_data", lambda lay: lay.map_data(RIG), "data/quadruped/map"),
    ("map_stage_model", lambda lay: lay.map_stage_model(RIG), "data/quadruped/map/model"),
    ("map_metrics", lambda lay: lay.map_metrics(RIG), "metrics/quadruped/map"),
    ("map_data suite", lambda lay: lay.map_data(RIG, "map_suite"), "data/quadruped/map_suite"),
    (
        "map_stage_model suite",
        lambda lay: lay.map_stage_model(RIG, "map_suite"),
        "data/quadruped/map_suite/model",
    ),
    (
        "map_metrics suite",
        lambda lay: lay.map_metrics(RIG, "map_suite"),
        "metrics/quadruped/map_suite",
    ),
    (
        "map_partial_metrics",
        lambda lay: lay.map_partial_metrics(RIG),
        "metrics/quadruped/map_partial",
    ),
    ("map_suite_page", lambda lay: lay.map_suite_page(RIG), "reports/map_suite/quadruped.md"),
    # reports (reports/build.py)
    ("figures", lambda lay: lay.figures(), "reports/figures"),
    ("result_figures", lambda lay: lay.result_figures(), "reports/figures/results"),
    ("tables", lambda lay: lay.tables(), "reports/tables"),
    ("index_page", lambda lay: lay.index_page(), "reports/index.html"),
    # the check_params stage's stamp (app/params.py)
    ("params_stamp", lambda lay: lay.params_stamp(), "data/params_checked.txt"),
    # a user's own runs (user_outputs.py, app/map_job.py, app/edits.py, app/synth.py)
    ("user_output", lambda lay: lay.user_output("map", RIG), "outputs/map/quadruped"),
    ("user_root", lambda lay: lay.user_root("models"), "outputs/models"),
]


@pytest.mark.parametrize(("kind", "call", "expected"), EXPECTED, ids=[e[0] for e in EXPECTED])
def test_each_path_kind_is_todays_string(kind, call, expected):
    assert str(call(Layout())) == expected


def test_replicate_paths_are_todays_strings():
    seed = Layout(replicate=2)
    assert str(seed.model(RIG, NN)) == "models/seeds/2/quadruped/nn-pca_gaussian-none"
    assert str(seed.model(RIG, GPR)) == "models/quadruped/gpr-none-multiquadric"
    assert str(seed.metrics_folder(RIG, "methods")) == "metrics/quadruped/methods_seed2"
    assert str(seed.metrics_file(RIG, "methods", "nn-none")) == (
        "metrics/quadruped/methods_seed2/nn-none.json"
    )


def test_roots_move_every_path_with_them():
    moved = Layout.from_paths({"data": "d", "models": "m", "metrics": "x", "reports": "r"})
    assert str(moved.latent_fit(RIG)) == "m/quadruped/latent/fit"
    assert str(moved.map_stage_model(RIG)) == "d/quadruped/map/model"
    assert str(moved.edits_refinement(RIG)) == "x/quadruped/edits/refinement"
    assert str(moved.index_page()) == "r/index.html"
    assert str(moved.params_stamp()) == "d/params_checked.txt"
    assert str(Layout.of_project("/p").map_suite_page(RIG)) == "/p/reports/map_suite/quadruped.md"
    assert Layout.ROOTS == ("data", "models", "metrics", "reports")


def test_a_map_stage_outside_the_two_is_refused():
    with pytest.raises(ValueError, match="map stage 'maps'"):
        Layout().map_data(RIG, "maps")


def test_callers_give_todays_strings():
    from rigmap.tracking.store import default_tracking_uri
    from rigmap.user_outputs import user_paths

    assert default_tracking_uri("/p") == "sqlite:////p/mlruns.db"
    assert user_paths(["paths.data=mine"]) == [
        "paths.models=outputs/models",
        "paths.metrics=outputs/metrics",
        "paths.reports=outputs/reports",
    ]


def test_checkout_paths_are_todays_strings(tmp_path, monkeypatch):
    assert Layout.project_conf("/p") == Path("/p/conf")
    assert Layout.tracking_store("/p") == Path("/p/mlruns.db")
    monkeypatch.setenv("RIGMAP_CACHE", str(tmp_path))
    assert Layout.blender_cache() == tmp_path / "blender"
    monkeypatch.delenv("RIGMAP_CACHE")
    assert Layout.blender_cache() == Path.home() / ".cache" / "rigmap" / "blender"


def test_packaged_conf_is_the_package_folder_and_holds_the_config():
    import rigmap

    assert packaged_conf() == Path(rigmap.__file__).resolve().parent / "conf"
    assert (packaged_conf() / "config.yaml").is_file()
    assert Layout.latent_scripts() == packaged_conf() / "latent" / "scripts"
    assert sorted(Layout.latent_scripts().glob("*.yaml")), "no latent scripts shipped"


# --- no path built outside Layout ----------------------------------------------------------
#: a project folder joined as a literal (``x / "models"``, ``Path("data")``) or ``__file__``
PATH_LITERAL = re.compile(
    r"""(?:/\s*|Path\(\s*|joinpath\(\s*)f?["'](?:data|models|metrics|reports|outputs|conf"""
    r"""|corpus|poses|samples|heldout|latent|edits|map|map_suite|map_partial|figures|tables"""
    r"""|results|seeds|refinement|fit|match|model|methods|samplers|kernels|mlruns\.db"""
    r"""|\.cache)["'/]|__file__"""
)
#: "file:line text" that may stay, and why (found by content, so line moves don't matter)
ALLOWED = {
    # Blender's worker runs inside Blender's Python, apart from rigmap: it finds its own
    # siblings (in_blender/*.py) beside itself, not a project path
    ("rigs/blender/in_blender/worker.py", "HERE = os.path.dirname(os.path.abspath(__file__))"),
    # the worker script rigmap hands to Blender: a file of the package, not a project path
    (
        "rigs/blender/environment.py",
        'WORKER_SCRIPT = Path(__file__).resolve().parent / "in_blender"',
    ),
}


def _path_literals(root: Path) -> list[tuple[str, int, str]]:
    found = []
    for path in sorted(root.rglob("*.py")):
        relative = path.relative_to(root).as_posix()
        if relative == "store/layout.py":
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if line.lstrip().startswith("#") or not PATH_LITERAL.search(line):
                continue
            if "resources.files(" in line:  # a file shipped inside the package, not the project's
                continue
            if any(relative == file and text in line for file, text in ALLOWED):
                continue
            found.append((relative, number, line.strip()))
    return found


def test_no_project_path_is_built_outside_layout():
    assert _path_literals(SRC) == []


def test_the_path_check_finds_a_literal(tmp_path):
    (tmp_path / "stage.py").write_text(
        'out = root / "models" / rig\nconf = Path(__file__).parent\nname = "models"\n'
    )
    assert [(f, n) for f, n, _ in _path_literals(tmp_path)] == [("stage.py", 1), ("stage.py", 2)]
