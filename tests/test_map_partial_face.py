"""FaceIK (Fig. 10) in the map_partial stage: the face posed from its landmarks on its test
clips, run from the stage's own config (conf/map_partial), with no motion-editing demo."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from rigmap.app.map_partial import map_partial_from_config
from rigmap.cli import find_config_dir

CONF = find_config_dir(Path(__file__).resolve().parents[1] / "conf")
SMALL_MODEL = ["budget.gpr_points=120", "budget.length_scales=3", "budget.cv_splits=2"]


def stage_config(root: Path, *overrides: str) -> dict:
    from rigmap.app.config import compose_config
    from rigmap.app.objects import plain
    from rigmap.app.stage import stage_config as with_rig_overrides

    paths = [f"paths.{k}={root / k}" for k in ("data", "models", "metrics")]
    cfg = compose_config(
        ["rig=face", "regressor=gpr", "kernel=multiquadric", *paths, *SMALL_MODEL, *overrides],
        CONF,
    )
    return plain(with_rig_overrides(cfg))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.rigs import load
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("face_project")
    face = load("face")
    layout = Layout(data=root / "data")
    write_corpora(face, layout, seed=0, fps=30, variation=1.0, log=lambda _: None)
    pose_corpora(face, layout, batch_size=512, progress=False, log=lambda _: None)
    return root, map_partial_from_config(stage_config(root, "map_partial.refine_every=8"))


def test_face_ik_scores_the_landmarks_on_the_test_clips(written):
    root, files = written
    folder = root / "metrics" / "face" / "map_partial"
    assert sorted(p.name for p in files) == ["partial_inputs.csv", "partial_inputs.json"]
    assert sorted(p.name for p in folder.iterdir()) == ["partial_inputs.csv", "partial_inputs.json"]
    record = json.loads((folder / "partial_inputs.json").read_text())
    assert record["subsets"]["landmarks"]["joints"][:2] == ["brow_l", "brow_r"]
    rows = pd.read_csv(folder / "partial_inputs.csv").set_index(["subset", "stage"])
    assert list(rows.index) == [(s, t) for s in ("full", "landmarks") for t in ("guess", "refined")]
    assert set(rows["given_joints"]) == {6}  # the six landmarks are every joint of the face
    guess, refined = rows.loc[("landmarks", "guess")], rows.loc[("landmarks", "refined")]
    assert refined["frames"] == -(-guess["frames"] // 8)  # every 8th test frame refined
    # the landmarks are reached: refinement brings them closer, to well under a centimetre
    assert refined["given_error_cm"] < guess["given_error_cm"]
    assert refined["given_error_cm"] < 0.5
    assert refined["given_error_cm"] == pytest.approx(refined["body_error_cm"])


def test_a_named_subset_list_still_picks_the_subsets(tmp_path):
    from rigmap.app.map_partial import MapPartialConfigError

    config = stage_config(tmp_path, "map_partial.input_joints=[feet]")
    with pytest.raises(MapPartialConfigError, match=r"\['feet'\]; rig 'face' has subsets"):
        map_partial_from_config(config)
