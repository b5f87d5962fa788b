"""The CMU walk retargeted onto Blender's Rigify human (a rig listing fingers before palms)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigmap.map import JointMap, tracks_from_bvh
from rigmap.rigs.blender.rigify import build_rigify_human

pytestmark = pytest.mark.blender
ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_02_walk.bvh"


def test_cmu_walk_on_rigify_human_keeps_its_bone_lengths():
    with build_rigify_human(workers=1) as rig:
        retarget = JointMap.from_yaml(ROOT / "conf/retarget/cmu_rigify_human.yaml")
        mapped = retarget.apply(rig, tracks_from_bvh(WALK))
        pose = rig.pose(rig.controls.defaults[None])
        rest = (np.asarray(pose.positions) + np.asarray(pose.cog)[:, None])[0]
    index = {n: rig.joint_names.index(n) for n in mapped.joint_names}
    checked = 0
    for k, name in enumerate(mapped.joint_names):
        parent = int(rig.parents[index[name]])
        while parent >= 0 and rig.joint_names[parent] not in index:
            parent = int(rig.parents[parent])
        if parent >= 0:
            p = mapped.joint_names.index(rig.joint_names[parent])
            length = np.linalg.norm(mapped.positions[:, k] - mapped.positions[:, p], axis=1)
            np.testing.assert_allclose(length, np.linalg.norm(rest[index[name]] - rest[parent]),
                                       rtol=1e-9)  # fmt: skip
            checked += 1
    assert checked == len(mapped.joint_names) - 1
    assert 4.0 < mapped.scale < 9.0
