"""Fig. 6 from the command line: `rigmap map` poses the quadruped from tracks of its four paws.

A small quadruped project (its train corpus and poses, as the animate and pose stages write
them) in a temporary folder; the paws' tracks are a test clip's, written as a CSV of the
rig's own joint names (no retarget map: rigmap.map.partial_tracks).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.cli import find_config_dir, main
from rigmap.map.partial_tracks import names_rig_joints, rig_joint_targets
from rigmap.map.tracks import JointTracks

CONF = find_config_dir(Path(__file__).resolve().parents[1] / "conf")
PAWS = ["front_paw_l", "front_paw_r", "hind_paw_l", "hind_paw_r"]
SMALL_MODEL = ["budget.gpr_points=80", "budget.length_scales=3", "budget.cv_splits=2"]


@pytest.fixture(scope="module")
def project(tmp_path_factory, quadruped):
    """data/quadruped/corpus and poses (seed 0), and the paws of the first test clip in m."""
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.animation.posing import PoseTable
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("quadruped_project")
    layout = Layout(data=root / "data", models=root / "models")
    write_corpora(quadruped, layout, seed=0, fps=24, variation=1.0)
    pose_corpora(quadruped, layout, batch_size=512, progress=False)
    poses = PoseTable.read(
        layout.poses("quadruped", "test"), rig="quadruped", n_joints=quadruped.n_joints
    )
    rows = np.flatnonzero(poses.table["clip"].to_numpy() == poses.clip_names[0])[:12]
    world = poses.positions()[rows] + poses.cog()[rows][:, None, :]
    columns = {"frame": np.arange(len(rows))}
    for name in PAWS:
        for axis, values in zip("xyz", world[:, quadruped.joint_names.index(name)].T, strict=True):
            columns[f"{name}.{axis}"] = values / 100.0  # metres: map.unit=m
    tracks = root / "paws.csv"
    pd.DataFrame(columns).to_csv(tracks, index=False)
    return root, tracks, world


def run_map(root: Path, tracks: Path, out: Path, *extra: str) -> int:
    return main(
        [
            "map",
            f"input={tracks}",
            "rig=quadruped",
            f"out={out}",
            f"paths.data={root / 'data'}",
            f"paths.models={root / 'models'}",
            "map.unit=m",
            "map.source_fps=24",
            "map.preview=false",
            "map.settings.refine_iterations=2",
            *SMALL_MODEL,
            *extra,
        ]
    )


def test_rigmap_map_poses_the_quadruped_from_its_four_paws(project, quadruped, tmp_path):
    import json

    root, tracks, world = project
    assert run_map(root, tracks, tmp_path / "out", "map.subset=feet") == 0
    folder = tmp_path / "out" / "paws"
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["mapped_joints"] == PAWS and summary["frames"] == 12
    # the paws are reached (the refined result, in cm: the tracks were in metres)
    assert summary["joint_error_rms_cm"] < 5.0
    controls = pd.read_parquet(folder / "controls.parquet")
    assert controls.shape == (12, 1 + quadruped.n_controls)
    # and the rest of the body follows: every joint within reach of the animator's pose
    pose = quadruped.pose(controls.drop(columns="frame").to_numpy())
    reached = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
    body_rms = float(np.sqrt(((reached - world) ** 2).sum(axis=2).mean()))
    assert body_rms < 0.5 * summary["rig_height_cm"]
    assert (root / "models" / "quadruped" / "map-feet").is_dir()  # the cached feet mapping


def test_paws_without_a_subset_of_them_are_refused_in_one_line(project, tmp_path, capsys):
    root, tracks, _ = project
    assert run_map(root, tracks, tmp_path / "out", "map.subset=effectors") != 0
    err = capsys.readouterr().err
    assert "effectors" in err and "pelvis" in err and "Traceback" not in err
    assert not (tmp_path / "out" / "paws").exists()


def test_tracks_of_the_rigs_joints_are_its_targets_in_cm(quadruped):
    positions = np.arange(2 * 4 * 3, dtype=float).reshape(2, 4, 3)
    names = ("hind_paw_r", "front_paw_l", "front_paw_r", "hind_paw_l")
    tracks = JointTracks(names, positions, 24.0, "m", "paws.csv")
    assert names_rig_joints(tracks, quadruped)
    targets = rig_joint_targets(tracks, quadruped)
    order = tuple(sorted(names, key=quadruped.joint_names.index))
    assert targets.joint_names == order  # the rig's order
    for k, name in enumerate(order):
        np.testing.assert_allclose(targets.positions[:, k], 100.0 * positions[:, names.index(name)])
    assert len(targets.undriven) == quadruped.n_joints - 4 and targets.scale == 100.0
    other = JointTracks(("LeftAnkle",), positions[:, :1], 24.0, "cm", "cmu.csv")
    assert not names_rig_joints(other, quadruped)
    with pytest.raises(ValueError, match="LeftAnkle"):
        rig_joint_targets(other, quadruped)
