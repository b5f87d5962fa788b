"""The ARKit face's animation written as Blender shape keys with an action, and read back."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rigmap.rigs.base import Control, ControlTable, Pose, Rig
from rigmap.rigs.blender.shape_keys import (
    ShapeKeyExportError,
    export_shape_key_blend,
    read_shape_key_blend,
    read_shape_key_mesh,
)
from rigmap.rigs.characters.arkit_face import build_arkit_face

pytestmark = [
    pytest.mark.blender,
]

#: the control fully on at frame 1 while every other one is off (the jaw: skinned, not a shape)
SOLO = "jawOpen"
ANIMATED = [
    SOLO,
    "eyeBlinkLeft",
    "mouthSmileLeft",
    "browInnerUp",
    "cheekPuff",
    "mouthPucker",
    "noseSneerRight",
    "eyeWideRight",
]
FRAMES = np.arange(1, 21)
FPS = 29.97


@pytest.fixture(scope="module")
def face():
    return build_arkit_face()


def smooth_table() -> pd.DataFrame:
    """Each control a raised cosine in [0, 1] at its own speed; at frame 1 only ``SOLO`` is on."""
    t = (FRAMES - 1) / (len(FRAMES) - 1)
    columns = {}
    for k, name in enumerate(ANIMATED):
        phase = np.pi if name == SOLO else 0.0
        columns[name] = 0.5 - 0.5 * np.cos(2 * np.pi * (1.0 + 0.15 * k) * t + phase)
    return pd.DataFrame({"frame": FRAMES, **columns})


@pytest.fixture(scope="module")
def exported(face, tmp_path_factory):
    folder = tmp_path_factory.mktemp("shape_keys")
    table = smooth_table()
    out = export_shape_key_blend(face, table, folder / "face.blend", fps=FPS)
    return out, table


def test_the_table_moves_used_controls_within_their_range(face):
    table = smooth_table()
    assert set(ANIMATED) <= set(face.used_controls)
    values = table[ANIMATED].to_numpy()
    assert values.min() >= 0.0 and values.max() <= 1.0
    assert np.ptp(values, axis=0).min() > 0.5


def test_the_action_plays_back_the_controls(exported):
    out, table = exported
    assert out.is_file() and out.stat().st_size > 10_000
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]  # no temp left
    played = read_shape_key_blend(out)
    assert played["frame"].tolist() == FRAMES.tolist()
    assert list(played.columns) == ["frame", *ANIMATED]
    error = np.abs(played[ANIMATED].to_numpy() - table[ANIMATED].to_numpy()).max()
    assert error <= 1e-5
    assert played.attrs["fps"] == pytest.approx(FPS, abs=1e-4)


def test_one_control_on_is_the_rigs_own_mesh(face, exported):
    out, table = exported
    row = table.iloc[0]
    assert row[SOLO] == 1.0 and (row[ANIMATED[1:]] == 0.0).all()
    in_blender = read_shape_key_mesh(out, FRAMES[0])
    Y = face.default_controls(1)
    Y[0, face.controls.index(SOLO)] = 1.0
    expected = face.mesh(Y)[0]
    assert np.abs(in_blender - expected).max() <= 1e-4  # cm
    rest = face.mesh(face.default_controls(1))[0]
    assert np.abs(expected - rest).max() > 0.5  # the jaw really opens


def test_several_controls_on_are_the_linear_sum_of_their_shapes(face, exported):
    """What the docstring promises: rest + sum of weight x (shape - rest), not the rig's mesh."""
    out, table = exported
    row = 9
    in_blender = read_shape_key_mesh(out, FRAMES[row])
    rest = face.mesh(face.default_controls(1))[0]
    singles = face.default_controls(len(ANIMATED))
    singles[np.arange(len(ANIMATED)), [face.controls.index(n) for n in ANIMATED]] = 1.0
    deltas = face.mesh(singles) - rest
    weights = table[ANIMATED].to_numpy()[row]
    linear = rest + np.einsum("k,kvd->vd", weights, deltas)
    assert np.abs(in_blender - linear).max() <= 1e-4


class _SkeletonRig(Rig):
    """A rig of joints only: no mesh to make shape keys of."""

    def __init__(self):
        self.name = "skeleton"
        self.controls = ControlTable([Control("a", "scalar", 0.0, 0.0, 1.0, True, "g")])
        self.joint_names = ["j"]

    def _pose(self, Y):
        n = len(Y)
        return Pose(np.zeros((n, 1, 3)), np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)))


@pytest.mark.parametrize(
    ("table", "file_name", "message"),
    [
        (pd.DataFrame({"jawOpen": [0.0]}), "x.blend", "no 'frame' column"),
        (
            pd.DataFrame({"frame": [1], "jawOpenn": [0.0]}),
            "x.blend",
            r"\['jawOpenn'\] are not controls",
        ),
        (
            pd.DataFrame({"frame": [1, 2], "jawOpen": [0.0, np.nan]}),
            "x.blend",
            "row 1, column 'jawOpen'",
        ),
        (
            pd.DataFrame(
                {"frame": [1, 2, 3], "jawOpen": [0.0, 0.1, 0.2], "cheekPuff": [0, 0, np.inf]}
            ),
            "x.blend",
            "row 2, column 'cheekPuff'",
        ),
        (pd.DataFrame({"frame": [1, 1], "jawOpen": [0.0, 1.0]}), "x.blend", "repeats frames"),
        (pd.DataFrame({"frame": [1], "jawOpen": [0.5]}), "x.fbx", r"must end in \.blend"),
        (pd.DataFrame({"frame": [1], "jawOpen": [11.0]}), "x.blend", "row 0, column 'jawOpen'"),
    ],
)
def test_bad_input_is_refused_and_writes_nothing(face, tmp_path, table, file_name, message):
    with pytest.raises(ShapeKeyExportError, match=message):
        export_shape_key_blend(face, table, tmp_path / file_name, fps=24)
    assert not list(tmp_path.iterdir())


def test_a_rig_without_a_mesh_is_refused(tmp_path):
    with pytest.raises(ShapeKeyExportError, match="rig 'skeleton' has no mesh"):
        export_shape_key_blend(
            _SkeletonRig(), pd.DataFrame({"frame": [1], "a": [0.0]}), tmp_path / "x.blend", fps=24
        )
    assert not list(tmp_path.iterdir())
    assert issubclass(ShapeKeyExportError, ValueError)
