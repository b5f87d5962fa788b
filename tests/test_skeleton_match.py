"""Skeleton matching (rigmap.map.skeleton_match) on both CMU conversions of ../shared/mocap,
on renamed and broken skeletons, and `rigmap map`'s use of it (rigmap.app.map_job.read_clips)."""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path

import numpy as np
import pytest
import yaml

from rigmap.animation.bvh import read_bvh
from rigmap.app.map_job import read_clips
from rigmap.map.joint_map import JointMap
from rigmap.map.skeleton_match import (
    UNKNOWN,
    FrameCheck,
    Skeleton,
    SkeletonMatchError,
    check_frames,
    match_bvh,
    match_skeleton,
    name_side_and_roles,
)
from rigmap.map.tracks import tracks_from_motion

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
CONF = ROOT / "conf"
CMU_131 = MOCAP / "cmu_131_01_walk.bvh"
HAHNE = MOCAP / "cmu_07_01.bvh"
RIGS = ["biped", "rigify_human"]
SHIPPED = {"biped": "cmu_biped", "rigify_human": "cmu_rigify_human"}


def _script():
    spec = importlib.util.spec_from_file_location(
        "match_cmu_skeletons", ROOT / "scripts" / "match_cmu_skeletons.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ROLES = _script().rig_roles(CONF / "map" / "default.yaml")


def motion_of(path: Path):
    assert path.is_file(), f"{path} is missing: the CMU clips ship in ../shared/mocap"
    return read_bvh(path)


def matched(motion, rig: str, tmp_path: Path, source: str = "clip.bvh"):
    positions = tracks_from_motion(motion, source).positions
    return match_bvh(
        motion, positions, rig, ROLES[rig], source=source, draft=tmp_path / "draft.yaml"
    )


def as_data(text: str) -> dict:
    data = yaml.safe_load(text)
    return {**data, "ignore": sorted(data["ignore"])}


def shipped(rig: str, rename=None) -> dict:
    data = yaml.safe_load((CONF / "retarget" / f"{SHIPPED[rig]}.yaml").read_text())
    rename = rename or (lambda name: name)
    data["joints"] = {k: rename(v) for k, v in data["joints"].items()}
    data["ignore"] = sorted(rename(n) for n in data["ignore"])
    return data


# --------------------------------------------------------------------------- the CMU files
@pytest.mark.parametrize("rig", RIGS)
def test_the_131_conversion_gives_the_shipped_map_exactly(rig, tmp_path):
    result = matched(motion_of(CMU_131), rig, tmp_path)
    assert as_data(result.text) == shipped(rig)
    assert not result.frames.tpose_at_0 and result.frames.glitches == ()
    assert not (tmp_path / "draft.yaml").exists()


@pytest.mark.parametrize("rig", RIGS)
def test_the_hahne_conversion_gives_the_shipped_map_under_its_own_names(rig, tmp_path):
    """Both conversions have one hierarchy: the shipped map renamed joint for joint (in
    hierarchy order) is what the other conversion's map must be."""
    cmu, hahne = Skeleton.from_bvh(motion_of(CMU_131)), Skeleton.from_bvh(motion_of(HAHNE))
    np.testing.assert_array_equal(cmu.parents, hahne.parents)
    rename = dict(zip(cmu.names, hahne.names, strict=True))
    assert rename["LeftKnee"] == "LeftLeg" and rename["lowerneck"] == "Neck"
    result = matched(motion_of(HAHNE), rig, tmp_path)
    assert as_data(result.text) == shipped(rig, rename.__getitem__)
    assert result.frames.tpose_at_0


@pytest.mark.parametrize("conversion", ["cmu_131", "cmu_hahne"])
@pytest.mark.parametrize("rig", RIGS)
def test_the_committed_matched_maps_are_current(conversion, rig, tmp_path):
    committed = JointMap.from_yaml(CONF / "retarget" / "matched" / f"{conversion}_{rig}.yaml")
    clip = CMU_131 if conversion == "cmu_131" else HAHNE
    fresh = matched(motion_of(clip), rig, tmp_path).retarget
    assert committed.joints == fresh.joints and set(committed.ignore) == set(fresh.ignore)
    assert (committed.up, committed.forward, committed.left) == ("+y", "+z", "+x")


# --------------------------------------------------------------------------- other skeletons
def _write_bvh(path: Path, names, parents, offsets, ends: dict, frames: np.ndarray) -> Path:
    """A BVH of the given hierarchy: the root with position and ZYX rotation channels, the
    others ZYX rotations; ``ends[j]`` is joint ``j``'s end-site offset."""
    lines = []

    def joint(j: int, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parents[j] < 0 else 'JOINT'} {names[j]}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:.6f}' for v in offsets[j])}")
        rotations = "Zrotation Yrotation Xrotation"
        position = "Xposition Yposition Zposition " if parents[j] < 0 else ""
        lines.append(f"{pad}  CHANNELS {6 if parents[j] < 0 else 3} {position}{rotations}")
        for child in [c for c in range(len(names)) if parents[c] == j]:
            joint(child, depth + 1)
        if j in ends:
            lines.extend(
                [
                    f"{pad}  End Site",
                    f"{pad}  {{",
                    f"{pad}    OFFSET {' '.join(f'{v:.6f}' for v in ends[j])}",
                    f"{pad}  }}",
                ]
            )
        lines.append(f"{pad}}}")

    joint(0, 0)
    motion = ["MOTION", f"Frames: {len(frames)}", "Frame Time: 0.0083333"]
    motion += [" ".join(f"{v:.6f}" for v in row) for row in frames]
    path.write_text("\n".join(["HIERARCHY", *lines, *motion]) + "\n")
    return path


def _variant(path: Path, motion, rename: dict, *, move: dict | None = None, edit=None) -> Path:
    """``motion``'s skeleton written with joints renamed, reparented (``move``: joint →
    new parent name) and ``edit(names, parents, offsets, ends)`` applied; 3 frames."""
    names = [rename.get(n, n) for n in motion.joint_names]
    parents = [int(p) for p in motion.parents]
    for joint, parent in (move or {}).items():
        parents[names.index(joint)] = names.index(parent)
    offsets = [np.array(o, dtype=float) for o in motion.offsets]
    ends = {int(p): motion.end_site_offsets[k] for k, p in enumerate(motion.end_site_parents)}
    if edit is not None:
        edit(names, parents, offsets, ends)
    order = _hierarchy_order(parents)
    index = {old: new for new, old in enumerate(order)}
    frames = np.zeros((3, 6 + 3 * (len(names) - 1)))
    frames[:, 1] = 17.0
    return _write_bvh(
        path,
        [names[j] for j in order],
        [index[parents[j]] if parents[j] >= 0 else -1 for j in order],
        [offsets[j] for j in order],
        {index[j]: e for j, e in ends.items()},
        frames,
    )


def _hierarchy_order(parents: list[int]) -> list[int]:
    order, stack = [], [parents.index(-1)]
    while stack:
        j = stack.pop()
        order.append(j)
        stack += [c for c in reversed(range(len(parents))) if parents[c] == j]
    return order


def test_scrambled_names_and_a_broken_topology_give_one_error_and_a_draft(tmp_path):
    """Meaningless names, and the right arm hung from the hips: the right arm's roles are
    named in the one-line error, and the draft map has them as ??? for the user to fill."""
    motion = motion_of(CMU_131)
    scrambled = {n: f"bone{k:02d}" for k, n in enumerate(motion.joint_names)}
    path = _variant(
        tmp_path / "scrambled.bvh",
        motion,
        scrambled,
        move={scrambled["RightCollar"]: scrambled["Hips"]},
    )
    draft = tmp_path / "out" / "scrambled.retarget.draft.yaml"
    bvh = read_bvh(path)
    positions = tracks_from_motion(bvh, str(path)).positions
    with pytest.raises(SkeletonMatchError) as error:
        match_bvh(bvh, positions, "biped", ROLES["biped"], draft=draft, source=str(path))
    message = str(error.value)
    assert "\n" not in message and str(path) in message and str(draft) in message
    for rig_joint in ("upper_arm_r (role upper_arm_r)", "forearm_r (role forearm_r)"):
        assert rig_joint in message
    assert f"{scrambled['Chest2']!r} has 1 arm branch(es) where two are expected" in message
    data = yaml.safe_load(draft.read_text())
    assert (
        data["joints"]["hand_r"] == UNKNOWN and data["joints"]["hand_l"] == scrambled["LeftWrist"]
    )
    assert data["joints"]["thigh_r"] == scrambled["RightHip"]


def test_scrambled_names_on_an_intact_skeleton_match_by_topology_alone(tmp_path):
    motion = motion_of(CMU_131)
    scrambled = {n: f"bone{k:02d}" for k, n in enumerate(motion.joint_names)}
    bvh = read_bvh(_variant(tmp_path / "scrambled.bvh", motion, scrambled))
    match = match_skeleton(Skeleton.from_bvh(bvh))
    assert match.problems == []
    assert match.by_name == 3  # only the end sites' "_end" (head and toe tips) say anything

    def renamed(name: str) -> str:
        stem = name.removesuffix("_end")
        return scrambled[stem] + name[len(stem) :]

    reference = match_skeleton(Skeleton.from_bvh(motion)).roles
    assert match.roles == {role: renamed(name) for role, name in reference.items()}


def _mixamo(names, parents, offsets, ends) -> None:
    """Mixamo's layout on the Hahne skeleton: clavicles with length, a HeadTop_End joint;
    and twist/roll joints as other tools add them."""
    for side, sign in (("Left", 1.0), ("Right", -1.0)):
        clavicle, arm = (
            names.index(f"mixamorig:{side}Shoulder"),
            names.index(f"mixamorig:{side}Arm"),
        )
        shift = np.array([sign * 1.2, 0.3, 0.0])
        offsets[clavicle] = offsets[clavicle] + shift
        offsets[arm] = offsets[arm] - shift
    head = names.index("mixamorig:Head")
    names.append("mixamorig:HeadTop_End")
    parents.append(head)
    offsets.append(np.array(ends.pop(head), dtype=float))
    ends[len(names) - 1] = np.array([0.0, 0.4, 0.0])
    # a roll leaf beside the left forearm, and a twist joint inside the right forearm
    arm, forearm = names.index("mixamorig:LeftArm"), names.index("mixamorig:LeftForeArm")
    names.append("mixamorig:LeftArmRoll")
    parents.append(arm)
    offsets.append(offsets[forearm] / 2)
    ends[len(names) - 1] = offsets[forearm] / 4
    forearm, hand = names.index("mixamorig:RightForeArm"), names.index("mixamorig:RightHand")
    names.append("mixamorig:RightForeArmTwist")
    parents.append(forearm)
    offsets.append(offsets[hand] / 2)
    parents[hand] = len(names) - 1
    offsets[hand] = offsets[hand] / 2


def test_mixamo_names_on_the_same_skeleton_are_matched(tmp_path):
    motion = motion_of(HAHNE)
    mixamo = {n: f"mixamorig:{n}" for n in motion.joint_names}
    mixamo.update(
        {
            "LowerBack": "mixamorig:Spine",
            "Spine": "mixamorig:Spine1",
            "Spine1": "mixamorig:Spine2",
            "Neck": "mixamorig:NeckBase",
            "Neck1": "mixamorig:Neck",
            "LeftHandIndex1": "mixamorig:LeftHandMiddle1",
            "RightHandIndex1": "mixamorig:RightHandMiddle1",
            "LThumb": "mixamorig:LeftHandThumb1",
            "RThumb": "mixamorig:RightHandThumb1",
        }
    )
    bvh = read_bvh(_variant(tmp_path / "mixamo.bvh", motion, mixamo, edit=_mixamo))
    result = matched(bvh, "biped", tmp_path, "mixamo.bvh")
    joints = result.retarget.joints
    assert joints["spine_2"] == "mixamorig:Spine1" and joints["spine_chest"] == "mixamorig:Spine2"
    assert joints["neck_1"] == "mixamorig:Neck" and joints["head"] == "mixamorig:Head"
    assert joints["head_end"] == "mixamorig:HeadTop_End"
    assert joints["upper_arm_l"] == "mixamorig:LeftArm"  # the clavicle (Shoulder) skipped
    assert joints["hand_r"] == "mixamorig:RightHand"
    assert joints["middle_1_l"] == "mixamorig:LeftHandMiddle1"
    assert (
        joints["thigh_r"] == "mixamorig:RightUpLeg" and joints["ball_l"] == "mixamorig:LeftToeBase"
    )
    assert result.match.by_name == len(result.match.roles) and result.match.problems == []


@pytest.mark.parametrize(
    ("name", "side", "role"),
    [
        ("mixamorig:LeftUpLeg", "l", "thigh"),
        ("Character1_RightForeArm", "r", "forearm"),
        ("Bip01 L Thigh", "l", "thigh"),
        ("l_hip", "l", "thigh"),
        ("L_Thigh", "l", "thigh"),
        ("thigh.R", "r", "thigh"),
        ("RightShin", "r", "shin"),
        ("LeftThigh", "l", "thigh"),
        ("RightToeEnd", "r", "toe_end"),
        ("Bip01 R UpperArm", "r", "upper_arm"),
        ("LeftToe_End", "l", "toe_end"),
        ("lhand", "l", "hand"),
        ("lowerback", None, "spine"),
        ("Hips", None, "hips"),
        ("LeftKnee", "l", "shin"),
        ("RFingers", "r", "fingers"),
    ],
)
def test_names_of_the_common_conventions(name, side, role):
    found_side, roles = name_side_and_roles(name)
    assert found_side == side and role in roles


# --------------------------------------------------------------------------- frames
def test_a_tpose_frame_and_a_planted_glitch_frame_are_found_and_repaired():
    motion = motion_of(HAHNE)
    values = motion.values.copy()
    values[5] = 0.0
    glitched = dataclasses.replace(motion, values=values)
    positions = glitched.global_positions(end_sites=True)
    names = Skeleton.from_bvh(motion).names
    match = match_skeleton(Skeleton.from_bvh(motion))
    check = check_frames(values, positions, names, match)
    assert check == FrameCheck(tpose_at_0=True, glitches=(5,))
    repaired = check.apply(positions)
    assert len(repaired) == len(positions) - 1  # the T-pose cut
    np.testing.assert_allclose(repaired[4], (positions[4] + positions[6]) / 2)
    np.testing.assert_array_equal(repaired[5], positions[6])
    cmu = motion_of(CMU_131)
    cmu_positions = cmu.global_positions(end_sites=True)
    cmu_check = check_frames(
        cmu.values,
        cmu_positions,
        Skeleton.from_bvh(cmu).names,
        match_skeleton(Skeleton.from_bvh(cmu)),
    )
    assert cmu_check == FrameCheck(tpose_at_0=False, glitches=())


def test_the_real_glitch_of_cmu_07_12_is_found():
    motion = motion_of(MOCAP / "cmu_07_12.bvh")
    skeleton = Skeleton.from_bvh(motion)
    check = check_frames(
        motion.values,
        motion.global_positions(end_sites=True),
        skeleton.names,
        match_skeleton(skeleton),
    )
    assert check == FrameCheck(tpose_at_0=True, glitches=(1,))


# --------------------------------------------------------------------------- rigmap map
OPTIONS = {
    "fps": 30,
    "first_frame": 0,
    "frames": 4,
    "rigs": {"biped": {"retarget": "cmu_biped", "roles": ROLES["biped"]}},
}


def test_map_matches_a_bvh_the_default_map_does_not_fit_and_saves_the_map(biped, tmp_path):
    log: list[str] = []
    out = tmp_path / "out"
    clips, retarget = read_clips([HAHNE], biped, OPTIONS, CONF, out, log.append)
    saved = out / "cmu_07_01.retarget.yaml"
    assert any(str(saved) in line for line in log), log
    assert any("frame 0 is a T-pose (excluded)" in line for line in log), log
    assert JointMap.from_yaml(saved).joints["thigh_l"] == "LeftUpLeg"
    assert retarget.name == "cmu_biped"  # same rig joints: the default's cached model
    assert clips[0].positions.shape == (4, 24, 3)
    assert sorted(p.name for p in out.iterdir()) == ["cmu_07_01.retarget.yaml"]


def test_map_keeps_the_default_map_where_it_fits_and_an_explicit_map_first(biped, tmp_path):
    out = tmp_path / "out"
    _, retarget = read_clips([CMU_131], biped, OPTIONS, CONF, out, print)
    assert retarget.name == "cmu_biped" and not out.exists()
    explicit = {**OPTIONS, "retarget": str(CONF / "retarget" / "matched" / "cmu_hahne_biped.yaml")}
    _, retarget = read_clips([HAHNE], biped, explicit, CONF, out, print)
    assert retarget.name == "cmu_hahne_biped" and not out.exists()
    forced = {**OPTIONS, "retarget": "auto"}
    _, retarget = read_clips([CMU_131], biped, forced, CONF, out, print)
    assert (out / "cmu_131_01_walk.retarget.yaml").is_file()


def test_map_of_an_unmatchable_bvh_is_one_error_and_writes_only_the_draft(biped, tmp_path):
    motion = motion_of(CMU_131)
    scrambled = {n: f"bone{k:02d}" for k, n in enumerate(motion.joint_names)}
    path = _variant(
        tmp_path / "odd.bvh", motion, scrambled, move={scrambled["LeftCollar"]: scrambled["Hips"]}
    )
    out = tmp_path / "out"
    with pytest.raises(SkeletonMatchError, match=r"unmatched upper_arm_l .*odd.retarget.draft"):
        read_clips([path], biped, OPTIONS, CONF, out, print)
    assert sorted(p.name for p in out.iterdir()) == ["odd.retarget.draft.yaml"]
