"""Table 1's network rows over replicate training seeds (issue #36 item 6).

The metrics are the committed quadruped Table 1 files (``metrics/quadruped/methods/``),
copied into a tmp tree; the replicate seeds are those files with their errors scaled, as
the ``evaluate_seed`` stage would leave them.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rigmap.app.fit import _replicate_of
from rigmap.regression.fitting import FitInputError
from rigmap.reports import ReportSettings, load_metrics
from rigmap.reports.seed_spread import NETWORK_METHODS, Spread, compare
from rigmap.reports.tables import methods_table
from rigmap.store import Layout, ModelId
from rigmap.store.layout import PER_FRAME

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "metrics" / "quadruped" / "methods"
COMMITTED_PER_FRAME = ROOT / "metrics" / "quadruped" / PER_FRAME / "methods"
CLIPS = ("Jumping & Playing", "Turning & Galloping", "Begging Excitedly")
SETTINGS = ReportSettings(
    rigs=("quadruped",), method_rigs=("quadruped",), sampler_rigs=(), clips=CLIPS
)


def _scaled_copy(source: Path, target: Path, scale: float) -> None:
    """A metrics JSON with every joint and ground-truth error multiplied by ``scale``."""
    record = json.loads(source.read_text())
    for numbers in (record["average"], *record["clips"].values()):
        numbers["joint_error"] *= scale
        numbers["ground_truth_error"] *= scale
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(record))


def _tree(folder: Path, scales: dict[int, float], shift: float = 1.0) -> Path:
    """``metrics/quadruped/methods`` (network rows times ``shift``; per-frame CSVs as they
    are) and one ``methods_seed<k>`` per ``scales`` entry (network rows times ``shift * scale``)."""
    metrics = folder / "metrics"
    methods = metrics / "quadruped" / "methods"
    shutil.copytree(COMMITTED, methods)
    shutil.copytree(COMMITTED_PER_FRAME, metrics / "quadruped" / PER_FRAME / "methods")
    for path in sorted(COMMITTED.glob("*.json")):
        if path.stem.partition("-")[0] not in NETWORK_METHODS:
            continue
        _scaled_copy(path, methods / path.name, shift)
        for seed, scale in scales.items():
            replicate = metrics / "quadruped" / f"methods_seed{seed}" / path.name
            _scaled_copy(path, replicate, shift * scale)
    return metrics


def _committed(method: str, sampler: str, measure: str = "joint_error") -> float:
    return json.loads((COMMITTED / f"{method}-{sampler}.json").read_text())["average"][measure]


def test_layout_puts_a_replicates_networks_and_metrics_in_their_own_folders():
    layout = Layout(replicate=2)
    assert layout.model("quadruped", ModelId("nn", "pca_gaussian")) == Path(
        "models/seeds/2/quadruped/nn-pca_gaussian-none"
    )
    assert layout.model("biped", ModelId("nn_joint_space")) == Path(
        "models/seeds/2/biped/nn_joint_space-none-none"
    )
    # the GPR (its learned Jacobian) stays seed 0's; metrics go to methods_seed<k>
    assert layout.model("quadruped", ModelId("gpr", "none", "multiquadric")) == Path(
        "models/quadruped/gpr-none-multiquadric"
    )
    assert layout.metrics_folder("quadruped", "methods") == Path("metrics/quadruped/methods_seed2")
    assert Layout().metrics_folder("quadruped", "methods") == Path("metrics/quadruped/methods")
    for bad in (0, -1, "1", True, 2**31):
        with pytest.raises(ValueError, match="replicate: expected null or a training seed"):
            Layout.from_paths({"models": "m"}, bad)


def test_a_replicate_fit_changes_only_the_networks_seed():
    config = {
        "paths": {"models": "models"},
        "replicate": 2,
        "regressor": {"_target_": "rigmap.regression.network.FeedForwardRegressor", "seed": 0},
    }
    layout, model = _replicate_of(config)
    assert model.seed == 2 and layout.replicate == 2
    _, seed0 = _replicate_of({**config, "replicate": None})
    assert seed0.seed == 0
    gpr = {"_target_": "rigmap.regression.gpr.GaussianProcessRegressor", "seed": 0}
    with pytest.raises(FitInputError, match="only the trained networks"):
        _replicate_of({**config, "regressor": gpr})


def test_table1_network_rows_give_median_and_min_max_over_seeds(tmp_path):
    metrics = _tree(tmp_path, {1: 0.9, 2: 1.2})
    tree = load_metrics(metrics, tmp_path / "data", SETTINGS)
    assert sorted(tree["quadruped"].replicates) == [1, 2]
    table = methods_table(tree, SETTINGS)
    rows = table.data.set_index(["motion", "method"])
    value = _committed("nn_joint_space", "none")
    row = rows.loc[("Average", "nn_joint_space")]
    assert row["joint_error"] == pytest.approx(value)  # seed 0's, as before
    assert row["joint_error_median"] == pytest.approx(value)
    assert row["joint_error_min"] == pytest.approx(0.9 * value)
    assert row["joint_error_max"] == pytest.approx(1.2 * value)
    truth = _committed("nn_joint_space", "none", "ground_truth_error")
    assert row["ground_truth_error_max"] == pytest.approx(1.2 * truth)
    assert row["seeds"] == 3
    clip = rows.loc[("Turning & Galloping", "nn")]
    assert clip["seeds"] == 3 and clip["joint_error_min"] < clip["joint_error_max"]
    gpr = rows.loc[("Average", "gpr_computed_jacobian")]
    assert gpr["seeds"] == 1
    assert gpr["joint_error_min"] == gpr["joint_error_median"] == gpr["joint_error"]
    # the Markdown/HTML cells: the median, and the min–max with the seed count beside
    shown = [r for r in table.rows if r[1] == "Joint-space NN (extra)"][-1]
    assert shown[3].endswith("(3)") and "–" in shown[3]


def test_a_comparison_within_the_spread_is_not_significant(tmp_path):
    """The committed joint-space NN (4.71 cm² in session 37's run) against GPR & CJ (4.90):
    seeds at 0.9x and 1.2x make the gap not significant; at 0.999x and 1.001x, significant."""
    network, gpr = _committed("nn_joint_space", "none"), _committed("gpr_computed_jacobian", "none")
    assert 0.9 * network < gpr < 1.2 * network and network < 0.99 * gpr  # what the test needs
    tree = load_metrics(_tree(tmp_path / "a", {1: 0.9, 2: 1.2}), tmp_path, SETTINGS)
    wide = methods_table(tree, SETTINGS)
    assert len([n for n in wide.notes if "re-trained with seeds 0, 1, 2" in n]) == 1
    span = f"{network * 0.9:.3g}–{network * 1.2:.3g} over 3 seeds"
    claim = f"Quadruped, Average joint error: Joint-space NN {network:.3g} cm² ({span}) "
    note = next(n for n in wide.notes if n.startswith(claim))
    assert f"against GPR & Computed Jacobian {gpr:.3g} cm²: not significant" in note
    narrow = methods_table(
        load_metrics(_tree(tmp_path / "b", {1: 0.999, 2: 1.001}), tmp_path, SETTINGS), SETTINGS
    )
    close = f"Joint-space NN {network:.3g} cm² ({network * 0.999:.3g}–{network * 1.001:.3g}"
    note = next(n for n in narrow.notes if close in n)
    assert note.endswith(f"GPR & Computed Jacobian {gpr:.3g} cm²: below by more than the spread.")


def test_compare_needs_the_gap_to_exceed_the_larger_spread():
    a, b = Spread.of([1.0, 1.1, 1.3]), Spread.of([1.5, 1.55, 1.6])
    assert "below by more than the spread" in compare("A", a, "B", b)  # gap 0.45 > 0.3
    assert "not significant" in compare("A", a, "B", Spread.of([1.2, 1.4]))
    assert "above by more than the spread" in compare("A", Spread.of([0.6, 0.7]), "the bar", 0.5)
    assert "not significant" in compare("A", Spread.of([0.45, 0.513]), "the bar", 0.5)


def _seed_spread(a: Path, b: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    command = [sys.executable, str(ROOT / "scripts" / "seed_spread.py"), str(a), str(b)]
    return subprocess.run(command, capture_output=True, text=True, env=env, timeout=120)


def test_seed_spread_script_flags_rows_that_disagree(tmp_path):
    a = _tree(tmp_path / "a", {1: 0.95, 2: 1.05})
    same = _tree(tmp_path / "same", {1: 1.04, 2: 0.97}, shift=1.02)  # within the spread
    done = _seed_spread(a, same)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    assert result["agree"] and len(result["rows"]) == 2 * 7
    moved = _tree(tmp_path / "moved", {1: 0.95, 2: 1.05}, shift=1.5)  # beyond it
    done = _seed_spread(a, moved)
    assert done.returncode == 1
    result = json.loads(done.stdout)
    assert "quadruped/nn_joint_space/joint_error" in result["disagree"]
    row = next(r for r in result["rows"] if r["row"] == "quadruped/nn_joint_space/joint_error")
    value = _committed("nn_joint_space", "none")
    assert row["median_a"] == pytest.approx(value)
    assert row["spread_a"] == pytest.approx(0.1 * value)
    assert row["median_b"] == pytest.approx(1.5 * value) and not row["agree"]
    assert _seed_spread(a, tmp_path / "nowhere").returncode == 2


def test_a_replicate_run_scores_only_the_network_rows_whatever_the_rig_lists():
    """A Blender rig's ``_overrides_`` list GPR and the mean predictor too (seed 0's models):
    the replicate evaluate keeps only the rows a re-trained network guesses, and the report
    refuses any other row in a replicate folder."""
    from omegaconf import OmegaConf

    from rigmap.app.evaluate import replicated_methods
    from rigmap.evaluation.checks import EvaluationSetupError
    from rigmap.evaluation.method import packaged_methods

    wolf = OmegaConf.load(Path(__file__).parents[1] / "conf" / "rig" / "rigify_wolf.yaml")
    wolf_list = list(wolf["_overrides_"]["evaluate"]["methods"])
    assert "gpr" in wolf_list and "mean" in wolf_list
    catalog = packaged_methods()
    assert replicated_methods(wolf_list, catalog) == (
        "nn",
        "nn_computed_jacobian",
        "nn_learned_jacobian",
    )
    assert replicated_methods(list(catalog), catalog) == tuple(
        name for name in catalog if name.startswith("nn")
    )
    # an unknown name is not dropped: the evaluation refuses it as without a replicate
    assert replicated_methods(["nn", "no_such_method"], catalog) == ("nn", "no_such_method")
    with pytest.raises(EvaluationSetupError, match=r"evaluate\.methods: a replicate seed"):
        replicated_methods(["gpr", "mean"], catalog)


def test_the_report_refuses_a_row_that_trains_no_network_in_a_replicate_folder(tmp_path):
    from rigmap.reports.metrics_tree import ReportInputError, read_replicates

    seed_folder = tmp_path / "rigify_wolf" / "methods_seed1"
    seed_folder.mkdir(parents=True)
    (seed_folder / "gpr-none.json").write_text("{}")
    with pytest.raises(ReportInputError, match=r"gpr-none\.json: unexpected file"):
        read_replicates(tmp_path / "rigify_wolf", "rigify_wolf")
