"""A mapped clip written as a .blend (F-curves on the used controls) and read back by bpy.

The file is opened by a separate Blender process (the worker environment's Python),
which lists every F-curve and its keys: the test compares them with the mapped values.
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from blender_script import run_bpy
from rigmap.map.blend_output import mapped_controls_table, write_mapped_blend
from rigmap.rigs import load
from rigmap.rigs.blender.export import read_blend_animation

pytestmark = [pytest.mark.blender]

READ_FCURVES = textwrap.dedent(
    """
    import json, sys
    import bpy
    bpy.ops.wm.open_mainfile(filepath=sys.argv[-2])
    scene = bpy.context.scene
    rig = bpy.data.objects["rig"]
    action = rig.animation_data.action
    curves = []
    for fcurve in rig.animation_data.action.fcurves if hasattr(action, "fcurves") else []:
        curves.append([fcurve.data_path, fcurve.array_index, fcurve.group.name,
                       [list(p.co) for p in fcurve.keyframe_points]])
    if not curves:  # Blender 5 layered actions: the F-curves live in the channelbag
        slot = rig.animation_data.action_slot
        for layer in action.layers:
            for strip in layer.strips:
                bag = strip.channelbag(slot)
                for fcurve in bag.fcurves:
                    curves.append([fcurve.data_path, fcurve.array_index, fcurve.group.name,
                                   [list(p.co) for p in fcurve.keyframe_points]])
    out = {"fps": scene.render.fps / scene.render.fps_base, "action": action.name,
           "frame_range": [scene.frame_start, scene.frame_end], "curves": curves}
    with open(sys.argv[-1], "w") as stream:
        json.dump(out, stream)
    """
)


@pytest.fixture(scope="module")
def human():
    return load("rigify_human")


def read_fcurves(blend, folder) -> dict:
    """Every F-curve of the file's rig, as a Blender process started here reads it."""
    return run_bpy(READ_FCURVES, str(blend), folder=folder)


def mapped_clip(rig, n_frames: int, seed: int = 0) -> np.ndarray:
    """``(F, C)`` controls: the used ones moving inside their ranges, the rest at rest."""
    rng = np.random.default_rng(seed)
    Y = rig.default_controls(n_frames)
    used = rig.controls.used_indices
    lower, upper = rig.controls.lower[used], rig.controls.upper[used]
    t = np.arange(n_frames)[:, None]
    Y[:, used] += 0.15 * (upper - lower) * np.sin(0.7 * t + rng.uniform(0, 6.3, len(used)))
    return np.clip(Y, rig.controls.lower, rig.controls.upper)


def test_fcurves_on_the_used_controls_hold_the_mapped_values(human, tmp_path):
    Y = mapped_clip(human, 5)
    out = write_mapped_blend(human, Y, 30.0, tmp_path / "walk.blend")
    assert out == tmp_path / "walk.blend" and out.stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.blend"]  # no temp left

    read = read_fcurves(out, tmp_path)
    assert read["fps"] == pytest.approx(30.0)
    assert read["frame_range"] == [0, 4]
    assert read["action"] == "rigify_human_mapped"
    assert len(read["curves"]) == len(human.used_controls)
    by_channel = {(path, index): (group, keys) for path, index, group, keys in read["curves"]}
    for name in human.used_controls:
        control = human.controls[name]
        bone, channel = name.rsplit(".", 1)
        kind = control.kind
        if kind == "scalar":
            path, index = f'pose.bones["{bone}"]["{channel}"]', 0
        else:
            attribute = {"t": "location", "r": "rotation_euler", "s": "scale"}[channel[0]]
            path, index = f'pose.bones["{bone}"].{attribute}', "xyz".index(channel[1])
        group, keys = by_channel[(path, index)]
        assert group == bone
        keys = np.asarray(keys)
        np.testing.assert_array_equal(keys[:, 0], np.arange(5))  # frames as in controls.parquet
        unit = 100.0 if kind == "translate" else 1.0  # Blender metres, rigmap cm
        expected = Y[:, human.controls.index(name)] / unit
        np.testing.assert_allclose(keys[:, 1], expected, atol=1e-6, err_msg=name)
    assert (np.ptp(Y[:, human.controls.used_indices], axis=0) > 0).mean() > 0.9  # curves move


def test_29_97_fps_and_a_first_frame(human, tmp_path):
    Y = mapped_clip(human, 3, seed=1)
    out = write_mapped_blend(human, Y, 29.97, tmp_path / "ntsc.blend", first_frame=1)
    read = read_fcurves(out, tmp_path)
    assert read["fps"] == pytest.approx(29.97, abs=1e-6)
    assert read["frame_range"] == [1, 3]


def test_bad_input_is_refused_and_nothing_is_written(human, tmp_path):
    Y = human.default_controls(3)
    target = tmp_path / "bad.blend"
    with pytest.raises(ValueError, match=r"\(frames, 1763\) for rig 'rigify_human'"):
        write_mapped_blend(human, Y[:, :10], 24.0, target)
    Y[1, human.controls.index("torso.tz")] = np.nan
    with pytest.raises(ValueError, match=r"frame 1, control 'torso.tz'"):
        write_mapped_blend(human, Y, 24.0, target)
    with pytest.raises(ValueError, match="no frames"):
        mapped_controls_table(human, Y[:0])
    with pytest.raises(ValueError, match="fps must be a positive number"):
        write_mapped_blend(human, human.default_controls(2), 0.0, target)
    with pytest.raises(ValueError, match=r"must end in \.blend"):
        write_mapped_blend(human, human.default_controls(2), 24.0, tmp_path / "bad.bvh")
    with pytest.raises(TypeError, match="not a Blender rig"):
        write_mapped_blend(load("biped"), np.zeros((2, 3)), 24.0, target)
    assert list(tmp_path.iterdir()) == []


def test_rigmap_map_on_rigify_human_writes_its_keys_into_a_blend(human, tmp_path):
    """The CLI's library path (rigmap.app.map_job) end to end on a Blender rig: every output of
    a clip, the .blend's F-curves holding controls.parquet, and Rigify's IK/FK switches held
    (map.rigs.rigify_human.settings.hold) at their corpus median."""
    from omegaconf import OmegaConf

    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.app.map_job import map_from_config
    from rigmap.app.stage import stage_config
    from rigmap.cli import compose_config, find_config_dir
    from rigmap.store import Layout

    root = Path(__file__).resolve().parents[1]
    conf = find_config_dir(root / "conf")
    layout = Layout(data=tmp_path / "data", models=tmp_path / "models")
    write_corpora(human, layout, seed=0, fps=24, variation=1.0, log=lambda _: None)
    pose_corpora(human, layout, batch_size=512, progress=False)
    walk = root.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"
    overrides = ["rig=rigify_human", f"paths.data={layout.data}", f"paths.models={layout.models}",
                 "budget.length_scales=3", "budget.cv_splits=2", f"input={walk}",
                 f"out={tmp_path / 'out'}", "map.first_frame=240", "map.frames=4",
                 "map.settings.refine_iterations=1", "map.preview=false"]  # fmt: skip
    config = OmegaConf.to_container(
        stage_config(compose_config(overrides, conf, config_name="map")), resolve=True
    )
    (clip,) = map_from_config(config, config_dir=conf, log=lambda _: None)
    assert sorted(p.name for p in clip.folder.iterdir()) == [
        "controls.parquet", "frames.parquet", "keys.json", "result.blend", "result.bvh",
        "summary.json", "targets.parquet"]  # fmt: skip
    assert clip.summary["frames"] == 4 and clip.summary["joint_error_rms_cm"] < 15.0

    controls = pd.read_parquet(clip.folder / "controls.parquet")
    corpus = pd.read_parquet(layout.data / "rigify_human" / "corpus" / "train.parquet")
    for switch in ("upper_arm_parent.L.IK_FK", "thigh_parent.R.IK_FK", "root.rz"):
        np.testing.assert_allclose(controls[switch], corpus[switch].median(), atol=1e-9)
    read = read_fcurves(clip.folder / "result.blend", tmp_path)
    assert read["frame_range"] == [0, 3] and read["fps"] == pytest.approx(30.0, abs=1e-3)
    assert read["action"] == "rigify_human_mapped"
    assert len(read["curves"]) == len(human.used_controls)
    # the file holds the reduced keys of keys.json, not a key on every frame
    keys = json.loads((clip.folder / "keys.json").read_text())["curves"]
    written = {(path, index): np.asarray(points) for path, index, _, points in read["curves"]}
    for name in ("torso.tx", "foot_ik.L.ty", "upper_arm_fk.R.rx", "thigh_parent.L.IK_FK"):
        unit = 100.0 if human.controls[name].kind == "translate" else 1.0
        expected = np.array([[k["frame"], k["value"] / unit] for k in keys[name]])
        np.testing.assert_allclose(written[_fcurve_key(human, name)], expected, atol=1e-5,
                                   err_msg=name)  # fmt: skip
    # played by Blender, the file poses the rig as controls.parquet does, within the
    # joint tolerance the key reduction states in summary.json
    played, pose = read_blend_animation(human, clip.folder / "result.blend")
    assert list(played["frame"]) == [0, 1, 2, 3]
    achieved = human.pose(controls[human.control_names].to_numpy()).positions
    gap = np.linalg.norm(pose.positions - achieved, axis=-1).max()
    assert gap <= clip.summary["key_tolerance_max_joint_error_cm"] + 1e-3


def _fcurve_key(rig, name: str) -> tuple[str, int]:
    """The F-curve ``(data_path, array_index)`` that holds control ``name``."""
    bone, channel = name.rsplit(".", 1)
    if rig.controls[name].kind == "scalar":
        return f'pose.bones["{bone}"]["{channel}"]', 0
    attribute = {"t": "location", "r": "rotation_euler"}[channel[0]]
    return f'pose.bones["{bone}"].{attribute}', "xyz".index(channel[1])
