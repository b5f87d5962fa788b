"""Joint positions written as BVH read back exactly by rigmap's BVH reader."""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.animation.bvh import read_bvh
from rigmap.map.bvh_export import BVHExportError, write_joint_bvh


def world(rig, controls):
    pose = rig.pose(controls)
    return np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]


def test_biped_motion_round_trips_through_bvh(biped, tmp_path):
    rng = np.random.default_rng(2)
    Y = biped.default_controls(6)
    Y[:, biped.controls.used_indices] += rng.normal(0, 0.08, (6, len(biped.used_controls)))
    positions = world(biped, Y)
    rest = world(biped, biped.default_controls(1))[0]
    path = write_joint_bvh(tmp_path / "biped.bvh", biped.joint_names, biped.parents, positions,
                           rest, fps=30.0)  # fmt: skip
    motion = read_bvh(path)
    assert motion.n_frames == 6 and motion.fps == pytest.approx(30.0)
    back = motion.global_positions()
    order = [motion.joint_names.index(n) for n in biped.joint_names]
    np.testing.assert_allclose(back[:, order], positions, atol=1e-5)  # 6 decimals in the file


def test_bad_positions_are_refused(biped, tmp_path):
    rest = world(biped, biped.default_controls(1))[0]
    bad = np.tile(rest, (2, 1, 1))
    bad[1, 3, 0] = np.inf
    with pytest.raises(BVHExportError, match="not all finite"):
        write_joint_bvh(tmp_path / "x.bvh", biped.joint_names, biped.parents, bad, rest, 30.0)
    with pytest.raises(BVHExportError, match=r"expected \(F > 0, 73, 3\)"):
        write_joint_bvh(tmp_path / "x.bvh", biped.joint_names, biped.parents, bad[:, :5], rest, 30)
    assert not (tmp_path / "x.bvh").exists()


def test_children_listed_before_their_parents_are_written_in_tree_order(tmp_path):
    names = ["hips", "finger", "palm"]
    parents = [-1, 2, 0]  # as Rigify lists a finger before its palm bone
    rest = np.array([[0.0, 100, 0], [0.0, 120, 0], [0.0, 110, 0]])
    positions = np.stack([rest, rest + np.array([[1.0, 0, 0], [3.0, 1, 0], [2.0, 0, 1]])])
    motion = read_bvh(write_joint_bvh(tmp_path / "t.bvh", names, parents, positions, rest, 24.0))
    assert motion.joint_names == ("hips", "palm", "finger")
    order = [motion.joint_names.index(n) for n in names]
    np.testing.assert_allclose(motion.global_positions()[:, order], positions, atol=1e-6)
