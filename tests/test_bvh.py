"""BVH reading and forward kinematics, on hand-made skeletons and on real CMU captures.

The real clips are from the CMU Graphics Lab Motion Capture Database:
The data used in this project was obtained from mocap.cs.cmu.edu.
The database was created with funding from NSF EIA-0196217.
"""

import itertools
import os
from pathlib import Path

import numpy as np
import pytest

from rigmap.animation import BVHError, parse_bvh, read_bvh

MOCAP = Path(os.environ.get("RIGMAP_MOCAP_DIR", Path(__file__).parents[2] / "shared" / "mocap"))
WALKS = {"cmu_131_01_walk.bvh": 994, "cmu_131_02_walk.bvh": 1247}

ARM = """HIERARCHY
ROOT root
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT arm
  {
    OFFSET 0 2 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 1 0 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 0 0 0 0 0 0 0 0
10 0 0 90 0 0 0 90 0
"""


def one_joint(order: str, values: str) -> str:
    return f"""HIERARCHY
ROOT hip
{{
  OFFSET 0 0 0
  CHANNELS 3 {order}
  End Site
  {{
    OFFSET 1 0 0
  }}
}}
MOTION
Frames: 1
Frame Time: 0.04
{values}
"""


# --- hand-made skeletons with known answers ---------------------------------------------
def test_forward_kinematics_on_a_two_bone_arm():
    motion = parse_bvh(ARM)
    assert motion.joint_names == ("root", "arm")
    assert motion.parents.tolist() == [-1, 0]
    assert motion.channels[0][:3] == ("Xposition", "Yposition", "Zposition")
    assert motion.fps == pytest.approx(30.0, rel=1e-5)
    positions = motion.global_positions(end_sites=True)
    assert positions.shape == (2, 3, 3)
    np.testing.assert_allclose(positions[0], [[0, 0, 0], [0, 2, 0], [1, 2, 0]], atol=1e-12)
    # frame 1: root moved to x=10 and turned 90 degrees about z, so the arm's offset
    # (0, 2, 0) points along -x; the arm turned 90 degrees about its y, so the tip's
    # offset (1, 0, 0) points along -z.
    np.testing.assert_allclose(positions[1], [[10, 0, 0], [8, 0, 0], [8, 0, -1]], atol=1e-12)
    assert motion.end_site_names == ("arm_end",)


def test_rotation_order_follows_the_channel_list():
    # The same angles (90 degrees about z and about x) in two orders put the tip apart:
    # Rz·Rx sends (1, 0, 0) to (0, 1, 0); Rx·Rz sends it to (0, 0, 1).
    zyx = parse_bvh(one_joint("Zrotation Yrotation Xrotation", "90 0 90"))
    xyz = parse_bvh(one_joint("Xrotation Yrotation Zrotation", "90 0 90"))
    np.testing.assert_allclose(zyx.global_positions(end_sites=True)[0, 1], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(xyz.global_positions(end_sites=True)[0, 1], [0, 0, 1], atol=1e-12)


# --- bad files -------------------------------------------------------------------------
def test_missing_motion_section():
    with pytest.raises(BVHError, match=r"arm\.bvh: no MOTION section"):
        parse_bvh(ARM.split("MOTION")[0], source="arm.bvh")


def test_unknown_channel_names_the_line():
    text = ARM.replace("CHANNELS 3 Zrotation", "CHANNELS 3 Wrotation")
    with pytest.raises(BVHError, match=r"line 9: unknown channel 'Wrotation' in joint 'arm'"):
        parse_bvh(text)


def test_wrong_value_count_names_the_line():
    text = ARM.replace("10 0 0 90 0 0 0 90 0", "10 0 0 90 0 0 0 90")
    with pytest.raises(BVHError, match=r"line 20: frame 1 has 8 values, expected 9"):
        parse_bvh(text)


def test_non_numeric_value_names_the_line():
    text = ARM.replace("10 0 0 90", "10 0 zero 90")
    with pytest.raises(BVHError, match=r"line 20: value 'zero' is not a number"):
        parse_bvh(text)


def test_more_lines_than_frames():
    with pytest.raises(BVHError, match=r"line 21: more motion lines than the 2 declared"):
        parse_bvh(ARM + "1 2 3 4 5 6 7 8 9\n")


def test_broken_hierarchy_names_the_line():
    text = ARM.replace("OFFSET 0 2 0", "OFFSET 0 two 0")
    with pytest.raises(BVHError, match=r"line 8: OFFSET needs 3 numbers, got 'two'"):
        parse_bvh(text)


# --- the real CMU clips -------------------------------------------------------------------
needs_mocap = pytest.mark.skipif(
    not all((MOCAP / name).is_file() for name in WALKS),
    reason=f"the CMU clips are not in {MOCAP} (set RIGMAP_MOCAP_DIR)",
)


@pytest.fixture(scope="module", params=sorted(WALKS))
def walk(request):
    if not (MOCAP / request.param).is_file():
        pytest.skip(f"{MOCAP / request.param} not found (set RIGMAP_MOCAP_DIR)")
    motion = read_bvh(MOCAP / request.param)
    return request.param, motion, motion.global_positions(end_sites=True)


@needs_mocap
def test_cmu_clip_sizes(walk):
    name, motion, positions = walk
    assert motion.n_frames == WALKS[name]
    assert motion.fps == pytest.approx(120.0, abs=0.01)
    assert motion.n_joints == 31 and len(motion.end_site_names) == 7
    assert motion.channel_count == 6 + 30 * 3
    assert positions.shape == (WALKS[name], 38, 3)
    # not one order for all: the arm and hand joints are keyed Z X Y, the rest Z Y X
    zxy = [
        n for n, c in zip(motion.joint_names, motion.channels, strict=True) if c[1] == "Xrotation"
    ]
    assert len(zxy) == 12
    assert {"LeftShoulder", "LeftElbow", "RightWrist", "RThumb"} <= set(zxy)
    assert motion.channels[motion.joint_index("LeftKnee")] == (
        "Zrotation",
        "Yrotation",
        "Xrotation",
    )


@needs_mocap
def test_cmu_bone_lengths_are_constant(walk):
    _, motion, positions = walk
    joints = positions[:, : motion.n_joints]
    child = np.arange(1, motion.n_joints)
    lengths = np.linalg.norm(joints[:, child] - joints[:, motion.parents[child]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(lengths[0], lengths.shape), atol=1e-9)
    np.testing.assert_allclose(lengths[0], np.linalg.norm(motion.offsets[child], axis=1), atol=1e-9)
    assert lengths.max() > 5.0  # the thigh and shin (CMU units), not a degenerate skeleton


@needs_mocap
def test_cmu_walk_moves_the_root_forward(walk):
    _, motion, positions = walk
    root = positions[:, motion.joint_index("Hips")]
    travel = root[-1] - root[0]
    head_height = positions[:, motion.joint_index("Head"), 1].mean() - root[:, 1].min()
    # both walks head along +z, by more than the character's own height
    assert travel[2] > 25.0
    assert abs(travel[0]) < 0.2 * travel[2]
    assert travel[2] > head_height
    # the hips are mostly at standing height (y is up; clip 01 has a deep crouch)
    assert np.median(root[:, 1]) > 0.9 * root[:, 1].max()


@needs_mocap
def test_cmu_walk_feet_take_turns_and_plant_near_the_floor(walk):
    _, motion, positions = walk
    ankles = {side: positions[:, motion.joint_index(f"{side}Ankle")] for side in ("Left", "Right")}
    window = np.ones(12) / 12  # 0.1 s at 120 fps
    speed = {
        side: np.convolve(
            np.linalg.norm(np.diff(a[:, [0, 2]], axis=0), axis=1) * motion.fps, window, "same"
        )
        for side, a in ankles.items()
    }
    floor = min(np.percentile(a[:, 1], 1) for a in ankles.values())
    swinging = np.where(
        speed["Left"] > speed["Right"] + 5.0,
        "L",
        np.where(speed["Right"] > speed["Left"] + 5.0, "R", ""),
    )
    order = [s for s in swinging if s]
    turns = 1 + sum(a != b for a, b in itertools.pairwise(order))
    assert turns >= 10  # at least ten swings, alternating left and right
    for stance, swing in (("Left", "Right"), ("Right", "Left")):
        frames = speed[swing] > speed[stance] + 5.0
        stance_height = np.median(ankles[stance][1:, 1][frames] - floor)
        swing_height = np.median(ankles[swing][1:, 1][frames] - floor)
        assert stance_height < 1.0  # CMU units, about 5 % of the body height
        assert swing_height > stance_height


@needs_mocap
def test_truncated_cmu_file_names_the_line(tmp_path):
    lines = (MOCAP / "cmu_131_01_walk.bvh").read_text().splitlines(keepends=True)
    motion_start = lines.index("MOTION\n") + 3  # first frame line (index)
    whole = tmp_path / "whole_lines.bvh"
    whole.write_text("".join(lines[: motion_start + 300]))
    with pytest.raises(BVHError) as caught:
        read_bvh(whole)
    message = str(caught.value)
    assert f"line {motion_start + 300}: truncated: file ends after 300 of the 994 frames" in message
    assert "whole_lines.bvh" in message

    cut = tmp_path / "cut_mid_line.bvh"
    cut.write_text("".join(lines[: motion_start + 300]) + lines[motion_start + 300][:200])
    with pytest.raises(
        BVHError, match=rf"line {motion_start + 301}: frame 300 has \d+ values, expected 96"
    ):
        read_bvh(cut)
