"""rigmap.map: joint tracks from files, and retarget maps onto the biped (real CMU clips)."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.map import JointMap, JointMapError, JointTracks, TracksError, read_tracks
from rigmap.map.tracks import tracks_from_bvh

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
CMU_BIPED = ROOT / "conf" / "retarget" / "cmu_biped.yaml"
CLIPS = ["cmu_131_01_walk.bvh", "cmu_131_02_walk.bvh"]


def rig_world(rig, controls):
    pose = rig.pose(controls)
    return np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]


def identity_map(rig, **options) -> JointMap:
    """Every rig joint driven by the source joint of the same name (source: Z up, metres)."""
    return JointMap.from_mapping(
        {
            "rig": rig.name,
            "joints": {n: n for n in rig.joint_names},
            "up": "+z",
            "forward": "-y",
            "left": "+x",
            "ground": "keep",
            **options,
        }
    )


def as_z_up_metres(world: np.ndarray) -> np.ndarray:
    """Rig world (Y up, +Z forward, cm) as a Z-up, -Y-forward source in metres."""
    return np.stack([world[..., 0], -world[..., 2], world[..., 1]], axis=-1) / 100.0


def test_exact_round_trip_through_other_axes_and_units(biped):
    rng = np.random.default_rng(3)
    controls = np.tile(biped.controls.defaults, (5, 1))
    used = biped.controls.used_indices
    controls[:, used] += rng.normal(0, 0.05, (5, len(used)))
    world = rig_world(biped, controls)
    tracks = JointTracks(biped.joint_names, as_z_up_metres(world), 30.0, "m", "synthetic")
    mapped = identity_map(biped, scale="unit", preserve_lengths=False).apply(biped, tracks)
    assert mapped.scale == 100.0
    assert mapped.joint_names == tuple(biped.joint_names)
    np.testing.assert_allclose(mapped.positions, world, atol=1e-9)


def test_auto_scale_recovers_the_unit_from_bone_lengths(biped):
    world = rig_world(biped, biped.controls.defaults[None])
    tracks = JointTracks(biped.joint_names, as_z_up_metres(world), 30.0, "source", "rest")
    mapped = identity_map(biped).apply(biped, tracks)
    assert mapped.scale == pytest.approx(100.0, rel=1e-12)
    np.testing.assert_allclose(mapped.positions, world, atol=1e-9)


@pytest.fixture(scope="module", params=CLIPS)
def cmu_tracks(request):
    path = MOCAP / request.param
    assert path.is_file(), f"{path} is missing: the CMU clips ship in ../shared/mocap"
    return tracks_from_bvh(path)


def test_cmu_clip_gets_the_rigs_bone_lengths_and_floor(biped, cmu_tracks):
    retarget = JointMap.from_yaml(CMU_BIPED)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every CMU joint is mapped or ignored on purpose
        mapped = retarget.apply(biped, cmu_tracks)
    assert mapped.positions.shape == (cmu_tracks.n_frames, len(retarget.joints), 3)
    rest = rig_world(biped, biped.controls.defaults[None])[0]
    index = {n: biped.joint_names.index(n) for n in mapped.joint_names}
    for k, name in enumerate(mapped.joint_names):
        parent = int(biped.parents[index[name]])
        while parent >= 0 and biped.joint_names[parent] not in index:
            parent = int(biped.parents[parent])
        if parent < 0:
            continue
        p = mapped.joint_names.index(biped.joint_names[parent])
        lengths = np.linalg.norm(mapped.positions[:, k] - mapped.positions[:, p], axis=1)
        want = np.linalg.norm(rest[index[name]] - rest[parent])
        np.testing.assert_allclose(lengths, want, rtol=1e-9)
    # CMU units are about 5.6-6.7 cm (a 1.7-1.8 m performer); the biped is 180 cm tall
    assert 4.0 < mapped.scale < 9.0
    lowest = mapped.positions[:, :, 1].min(axis=1)
    assert np.percentile(lowest, 5) == pytest.approx(rest[:, 1].min(), abs=1e-9)
    # the walk travels: the pelvis moves more than a metre over the clip
    travel = np.ptp(mapped.positions[:, 0, [0, 2]], axis=0).max()
    assert travel > 100.0
    assert "index_1_l" in mapped.undriven and "pelvis" not in mapped.undriven


def test_unused_source_joints_are_listed(biped, cmu_tracks):
    data = {"rig": "biped", "joints": {"pelvis": "Hips", "head": "Head"}}
    with pytest.warns(UserWarning, match="LeftKnee") as record:
        mapped = JointMap.from_mapping(data).apply(biped, cmu_tracks)
    assert "LeftKnee" in mapped.unused and "Hips" not in mapped.unused
    assert len(record) == 1


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"joints": {"pelvis": "Hips", "tail": "Head"}}, "has no joints ['tail']"),
        ({"joints": {"pelvis": "Hips", "head": "Skull"}}, "'Skull' (drives 'head')"),
        ({"joints": {"pelvis": "Hips", "spine_chest": "Chest2", "clavicle_l": "LeftCollar"}},
         "'spine_chest' -> 'clavicle_l' maps to source 'Chest2' -> 'LeftCollar', which has no"),
        ({"joints": {"head": "Head", "foot_l": "LeftAnkle"}}, "have no mapped ancestor"),
        ({"up": "+y", "forward": "+y"}, "three different source axes"),
        ({"up": "up"}, "must be one of"),
        ({"scale": -2}, "positive number"),
        ({"scale": "unit"}, "has no stated unit"),
        ({"rig": "quadruped"}, "for rig 'quadruped', not 'biped'"),
        ({"colour": "red"}, "unknown keys ['colour']"),
    ],
)  # fmt: skip
def test_bad_maps_name_what_is_wrong(biped, cmu_tracks, change, message):
    data = {"rig": "biped", "joints": {"pelvis": "Hips", "head": "Head"}, **change}
    with pytest.raises(JointMapError, match=re.escape(message)), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        JointMap.from_mapping(data).apply(biped, cmu_tracks)


def test_tracks_files_round_trip_and_bad_files_are_named(tmp_path):
    positions = np.arange(2 * 2 * 3, dtype=float).reshape(2, 2, 3)
    table = pd.DataFrame({"frame": [0, 1]})
    for j, name in enumerate(["hip", "knee"]):
        for a, axis in enumerate("xyz"):
            table[f"{name}.{axis}"] = positions[:, j, a]
    table.to_csv(tmp_path / "t.csv", index=False)
    table.to_parquet(tmp_path / "t.parquet")
    np.savez(tmp_path / "t.npz", positions=positions, joint_names=np.array(["hip", "knee"]), fps=60)
    for name in ("t.csv", "t.parquet", "t.npz"):
        tracks = read_tracks(tmp_path / name, unit="m", fps=60)
        assert tracks.joint_names == ("hip", "knee") and tracks.fps == 60
        np.testing.assert_array_equal(tracks.positions, positions)
    table.drop(columns=["knee.z"]).to_csv(tmp_path / "gap.csv", index=False)
    with pytest.raises(TracksError, match=r"gap\.csv: joints missing coordinate columns: \{'knee'"):
        read_tracks(tmp_path / "gap.csv", unit="m", fps=60)
    table.assign(**{"hip.y": [0.0, np.nan]}).to_csv(tmp_path / "nan.csv", index=False)
    with pytest.raises(TracksError, match=r"nan\.csv: joint 'hip' y is nan at frame 1"):
        read_tracks(tmp_path / "nan.csv", unit="m", fps=60)
    table.iloc[:0].to_csv(tmp_path / "empty.csv", index=False)
    with pytest.raises(TracksError, match=r"empty\.csv: the clip is empty"):
        read_tracks(tmp_path / "empty.csv", unit="m", fps=60)
    with pytest.raises(TracksError, match=r"pass map\.source_fps="):
        read_tracks(tmp_path / "t.csv", unit="m")
    with pytest.raises(TracksError, match="unknown length unit 'feet'"):
        read_tracks(tmp_path / "t.csv", unit="feet", fps=60)
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(TracksError, match=r"bad\.npz: not a readable npz"):
        read_tracks(tmp_path / "bad.npz", unit="m")
    with pytest.raises(FileNotFoundError, match=r"none\.csv"):
        read_tracks(tmp_path / "none.csv", unit="m", fps=60)
