"""map_clip on a real CMU walk onto the biped, with a mapping trained on the biped's corpus."""

from __future__ import annotations

import dataclasses
import fnmatch
from pathlib import Path

import numpy as np
import pytest

from rigmap.animation.library import build_corpus
from rigmap.map import JointMap, tracks_from_bvh
from rigmap.map.clip import MapError, MapSettings, held_controls, map_clip
from rigmap.map.partial import JointSubset, SubsetMapping
from rigmap.regression import GaussianProcessRegressor
from rigmap.regression.features import inverse_features
from rigmap.regression.kernels import MultiquadricKernel
from rigmap.rigs.base import Pose, Rig

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_02_walk.bvh"


@pytest.fixture(scope="module")
def trained(biped):
    """The biped's train corpus and a GPR on the joints the CMU map drives."""
    Y = build_corpus(biped, "train", seed=0).values()
    pose = biped.pose(biped.expand_used(Y))
    X = inverse_features(pose.positions, pose.cog, pose.cog_rotation, n_joints=biped.n_joints,
                         where="biped corpus")  # fmt: skip
    retarget = JointMap.from_yaml(ROOT / "conf/retarget/cmu_biped.yaml")
    subset = JointSubset("cmu", "biped", tuple(retarget.joints), "pelvis", "thigh_l", "thigh_r")
    regressor = GaussianProcessRegressor(MultiquadricKernel(), n_points=150, n_length_scales=5,
                                         cv_splits=2, progress=False)  # fmt: skip
    mapping = SubsetMapping.fit(biped, subset, X, Y, regressor)
    targets = retarget.apply(biped, tracks_from_bvh(WALK))
    short = dataclasses.replace(targets, positions=targets.positions[240:264:2], fps=60.0)
    return mapping, short, Y.std(axis=0), np.median(Y, axis=0)


def test_refinement_brings_the_rig_onto_the_mocap(biped, trained):
    mapping, targets, std, median = trained
    settings = MapSettings(refine_iterations=0, feet=("foot_l", "foot_r"), key_tolerance_cm=1.0)
    guess = map_clip(biped, targets, mapping, settings, control_std=std, hold_values=median)
    refined = map_clip(biped, targets, mapping, dataclasses.replace(settings, refine_iterations=2),
                       control_std=std, hold_values=median)  # fmt: skip
    assert guess.controls.shape == (12, biped.n_controls)
    assert refined.frame_error_cm.mean() < 0.5 * guess.frame_error_cm.mean()
    assert refined.seconds["refine_rig_evaluations"] > 0
    for result in (guess, refined):
        unused = np.setdiff1d(np.arange(biped.n_controls), biped.controls.used_indices)
        defaults = np.broadcast_to(biped.controls.defaults[unused], (12, len(unused)))
        np.testing.assert_array_equal(result.controls[:, unused], defaults)
        for k, name in enumerate(biped.used_controls):
            if any(fnmatch.fnmatch(name, p) for p in settings.hold):
                column = biped.controls.used_indices[k]
                np.testing.assert_allclose(result.controls[:, column], median[k], atol=1e-12)
        assert result.keys.max_joint_error_cm <= 1.0
        assert result.keys.key_count <= 12 * len(biped.used_controls)


def test_a_mapping_for_other_joints_is_refused(biped, trained):
    mapping, targets, std, median = trained
    fewer = dataclasses.replace(targets, joint_names=targets.joint_names[:-1],
                                positions=targets.positions[:, :-1])  # fmt: skip
    with pytest.raises(MapError, match=r"needs joints \['toe_r'\]"):
        map_clip(biped, fewer, mapping, MapSettings(), control_std=std, hold_values=median)
    with pytest.raises(MapError, match="refine_iterations"):
        MapSettings(refine_iterations=1.5)


def test_outputs_folder_holds_what_the_result_says(biped, trained, tmp_path):
    import json

    import pandas as pd

    from rigmap.animation.bvh import read_bvh
    from rigmap.map.outputs import write_map_outputs

    mapping, targets, std, median = trained
    result = map_clip(biped, targets, mapping, MapSettings(refine_iterations=0, feet=("foot_l",
                      "foot_r")), control_std=std, hold_values=median)  # fmt: skip
    folder = write_map_outputs(tmp_path / "walk", result, biped).folder
    controls = pd.read_parquet(folder / "controls.parquet")
    assert list(controls.columns) == ["frame", *biped.control_names]
    np.testing.assert_array_equal(controls[biped.control_names].to_numpy(), result.controls)
    frames = pd.read_parquet(folder / "frames.parquet")
    np.testing.assert_allclose(frames["joint_error_cm"], result.frame_error_cm)
    summary = json.loads((folder / "summary.json").read_text())
    rms = float(np.sqrt((result.frame_error_cm**2).mean()))
    assert summary["joint_error_rms_cm"] == pytest.approx(rms)
    assert summary["keys"] == result.keys.key_count
    assert 170 < summary["rig_height_cm"] < 190
    keys = json.loads((folder / "keys.json").read_text())["curves"]
    assert sum(len(v) for v in keys.values()) == result.keys.key_count
    motion = read_bvh(folder / "result.bvh")
    pose = biped.pose(result.controls)
    world = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
    order = [motion.joint_names.index(n) for n in biped.joint_names]
    np.testing.assert_allclose(motion.global_positions()[:, order], world, atol=1e-5)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk"]


@pytest.fixture(scope="module")
def walk_2s(biped):
    """Two seconds of the walk at 30 fps (about two steps per foot)."""
    retarget = JointMap.from_yaml(ROOT / "conf/retarget/cmu_biped.yaml")
    targets = retarget.apply(biped, tracks_from_bvh(WALK))
    return dataclasses.replace(targets, positions=targets.positions[240:480:4], fps=30.0)


FEET = ("foot_l", "foot_r", "ball_l", "ball_r")


def test_planted_heels_and_toes_hold_to_a_tenth_of_a_mm_in_the_keys(biped, trained, walk_2s):
    from rigmap.map.world_subset_rig import WorldSubsetRig

    mapping, _, std, median = trained
    settings = MapSettings(refine_iterations=1, feet=FEET, key_tolerance_cm=0.5)
    result = map_clip(biped, walk_2s, mapping, settings, control_std=std, hold_values=median)
    planted = result.contacts.planted
    assert planted.any(axis=0).all() and planted.mean() < 0.9  # every joint plants and lifts
    # the output (the keys' values on every frame) holds each plant where it was pinned
    world = WorldSubsetRig(biped, result.joint_names).evaluate(result.controls)
    for k, foot in enumerate(result.contacts.feet):
        j = result.joint_names.index(foot)
        for first, last in result.contacts.intervals(k):
            ground = world[first : last + 1, j][:, [0, 2]]
            pin = result.targets[first : last + 1, j][:, [0, 2]]
            assert np.linalg.norm(ground - pin, axis=1).max() <= 0.1
            assert np.ptp(result.targets[first : last + 1, j][:, [0, 2]], axis=0).max() == 0
    assert result.contact_slip_cm <= 0.1
    assert result.skate_result_cm <= result.skate_source_cm
    assert result.keys.max_joint_error_cm <= 0.5
    unpinned = map_clip(biped, walk_2s, mapping, dataclasses.replace(settings, pin_feet=False),
                        control_std=std, hold_values=median)  # fmt: skip
    assert unpinned.skate_result_cm > 5 * result.skate_result_cm  # the hold is what pins


def test_planted_frames_given_by_the_caller_are_the_ones_held(biped, trained, walk_2s):
    """A path edit knows its stance frames (rigmap.map.path_edit): map_clip holds those, in the
    mapping's own foot order, instead of detecting them; a mismatch is one clear error."""
    from rigmap.map.contacts import Contacts

    mapping, _, std, median = trained
    settings = MapSettings(refine_iterations=0, feet=FEET)
    frames = len(walk_2s.positions)
    given = np.zeros((frames, 4), dtype=bool)
    given[: frames // 2, 0] = given[frames // 2 :, 3] = True  # ball_r, then foot_l
    planted = Contacts(("ball_r", "ball_l", "foot_r", "foot_l"), given)
    options = {"control_std": std, "hold_values": median}
    result = map_clip(biped, walk_2s, mapping, settings, planted=planted, **options)
    assert result.contacts.feet == FEET
    expected = given[:, [3, 2, 1, 0]]
    np.testing.assert_array_equal(result.contacts.planted, expected)
    short = Contacts(planted.feet, given[:-1])
    with pytest.raises(MapError, match="planted frames given for feet"):
        map_clip(biped, walk_2s, mapping, settings, planted=short, **options)


def test_the_hold_moves_only_the_legs_controls(biped, trained, walk_2s):
    """Root motion, the COG and the body stay as mapped: the foot controls found by
    probing the rig are the legs' IK and foot-roll controls, none held."""
    from rigmap.map.contact_hold import foot_controls
    from rigmap.map.contacts import detect_contacts

    _, _, std, median = trained
    joints = list(walk_2s.joint_names)
    contacts = detect_contacts(walk_2s.positions, FEET, joints, walk_2s.fps)
    scale = std.copy()
    scale[held_controls(biped, MapSettings().hold)] = 0.0
    row = biped.expand_used(median[None])[0]
    flags, moves = foot_controls(biped, row, contacts, "pelvis", scale)
    names = [biped.used_controls[k] for k in np.flatnonzero(flags)]
    assert {"leg_l_ik.tx", "leg_l_ik.tz", "leg_r_ik.tx", "leg_r_ik.tz"} <= set(names)
    assert all(n.startswith(("leg_l", "leg_r")) and not n.endswith(".ik_fk") for n in names)
    left = [k for k, n in enumerate(names) if n.startswith("leg_l")]
    assert not moves[np.flatnonzero(flags)[left]][:, [1, 3]].any()  # left controls: left foot


def test_no_euler_flip_on_a_walk_that_turns_through_180_degrees(biped, trained, walk_2s):
    from rigmap.map.curves import count_flips

    mapping, _, std, median = trained
    turned = walk_2s.positions.copy()
    angle = np.linspace(np.radians(170), np.radians(190), len(turned))  # heading crosses ±π
    c, s = np.cos(angle), np.sin(angle)
    x, z = turned[:, :, 0].copy(), turned[:, :, 2].copy()
    turned[:, :, 0] = c[:, None] * x + s[:, None] * z
    turned[:, :, 2] = -s[:, None] * x + c[:, None] * z
    targets = dataclasses.replace(walk_2s, positions=turned)
    kinds = [biped.controls.kinds[i] for i in biped.controls.used_indices]
    guess = mapping.predict(
        turned[:, [targets.joint_names.index(j) for j in mapping.subset.joints]]
    )
    assert count_flips(guess, kinds) > 0  # predicted frame by frame, the heading wraps
    settings = MapSettings(refine_iterations=1, feet=FEET)
    result = map_clip(biped, targets, mapping, settings, control_std=std, hold_values=median)
    used = result.controls[:, biped.controls.used_indices]
    assert result.flips == 0 == count_flips(used, kinds)
    rotate = np.array([k == "rotate" for k in kinds])
    assert np.abs(np.diff(used[:, rotate], axis=0)).max() < 1.0


def test_round_trip_bvh_map_bvh_of_the_rig(biped, trained, walk_2s, tmp_path):
    """CMU BVH -> map -> the rig's BVH (``result.bvh``) -> map again: the rig's own motion
    reads back exactly (up to the floor alignment) through an identity retarget map and
    maps back onto itself within the mapping's own error (GPR of 150 points, 2 iterations),
    with no flip and no more skate."""
    from rigmap.map.outputs import write_map_outputs

    mapping, _, std, median = trained
    settings = MapSettings(refine_iterations=2, feet=FEET)
    first = map_clip(biped, walk_2s, mapping, settings, control_std=std, hold_values=median)
    folder = write_map_outputs(tmp_path / "first", first, biped).folder
    joints = {j: j for j in mapping.subset.joints}
    identity = JointMap.from_mapping({"rig": "biped", "joints": joints}, source_file="identity")
    with pytest.warns(UserWarning, match="drive no rig joint"):  # fingers: not in the subset
        again = identity.apply(biped, tracks_from_bvh(folder / "result.bvh"))
    assert again.scale == pytest.approx(1.0, rel=0.01)  # the rig's own bone lengths
    second = map_clip(biped, again, mapping, settings, control_std=std, hold_values=median)
    # read back: bones rebuilt at rest lengths, the lowest joint set on the floor (a shift)
    read = again.positions[:, [again.joint_names.index(j) for j in first.joint_names]]
    shift = (read - first.achieved).mean(axis=(0, 1))
    moved = np.linalg.norm(read - first.achieved - shift, axis=2)  # bones at rest lengths
    assert np.sqrt((moved**2).mean()) < 0.5 and abs(shift[1]) > 10 * max(abs(shift[[0, 2]]))
    distance = np.linalg.norm(second.achieved - (first.achieved + shift), axis=2)
    assert np.sqrt((distance**2).mean()) < 2.5  # cm on the 24 joints: the map's own error
    assert np.sqrt((first.frame_error_cm**2).mean()) > 2.0  # the real mocap was harder
    assert second.flips == 0 and second.skate_result_cm <= first.skate_result_cm + 0.01


class Float32Biped(Rig):
    """The biped with its positions rounded to float32, as Blender's rigs compute them."""

    def __init__(self, rig):
        self.inner, self.name, self.controls = rig, rig.name, rig.controls
        self.joint_names, self.parents = rig.joint_names, rig.parents
        self.differentiable, self.computes_in_float32 = False, True
        self.length_unit, self.description = rig.length_unit, "float32 biped"

    def _pose(self, Y) -> Pose:
        pose = self.inner.pose(np.asarray(Y, dtype=np.float64))
        rounded = (np.asarray(p, dtype=np.float32).astype(np.float64) for p in pose)
        return Pose(*rounded)


def test_foot_controls_of_a_float32_rig_are_found_through_its_rounding(biped, trained, walk_2s):
    from rigmap.map.contact_hold import foot_controls
    from rigmap.map.contacts import detect_contacts

    _, _, std, median = trained
    contacts = detect_contacts(walk_2s.positions, FEET, list(walk_2s.joint_names), walk_2s.fps)
    scale = std.copy()
    scale[held_controls(biped, MapSettings().hold)] = 0.0
    row = biped.expand_used(median[None])[0]
    exact, _ = foot_controls(biped, row, contacts, "pelvis", scale)
    rounded, _ = foot_controls(Float32Biped(biped), row, contacts, "pelvis", scale)
    assert not (rounded & ~exact).any()  # rounding adds no control (no root, no spine)
    names = {biped.used_controls[k] for k in np.flatnonzero(rounded)}
    for side in "lr":  # and loses none that moves a planted foot more than a rounding
        assert {f"leg_{side}_ik.tx", f"leg_{side}_ik.tz", f"leg_{side}.roll"} <= names
