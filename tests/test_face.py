"""The built-in face rig: 49 controls -> 6 landmarks (Table 3's facial rig)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from rigmap.refine import jacobian
from rigmap.rigs import RigInputError, load
from rigmap.rigs.characters.face import JAW_OPEN_FULL, FaceRig
from rigmap.rigs.mesh.blendshapes import CombinationShapes, CombinationSpec

LANDMARKS = ["brow_l", "brow_r", "mouth_corner_l", "mouth_corner_r", "upper_lip", "chin"]


@pytest.fixture(scope="module")
def face():
    return load("face")


def _pose(rig, **values) -> np.ndarray:
    y = rig.controls.defaults.copy()
    for name, value in values.items():
        y[rig.controls.index(name.replace("__", "."))] = value
    return y


def test_describe_counts(face):
    assert len(face.controls) >= 45
    assert face.n_joints == 6 and face.joint_names == LANDMARKS
    assert face.parents is None and face.differentiable
    assert face.n_vertices >= 500 and face.faces.shape[1] == 3
    summary = face.controls.summary()
    assert summary["used"] == summary["total"] == 49
    assert set(summary["by_group"]) == {"brows", "eyes", "cheeks", "nose", "mouth", "jaw"}
    kinds = dict(zip(face.control_names, face.controls.kinds, strict=True))
    assert kinds["jaw.rx"] == "rotate" and kinds["jaw.tz"] == "translate"
    assert kinds["mouth_smile_l"] == "scalar"


def test_rest_pose_gives_the_rest_landmarks(face):
    pose = face.pose(face.default_controls(1))
    rest = face.rest_vertices[face.joint_vertices] - pose.cog[0]
    np.testing.assert_allclose(pose.positions[0], rest, atol=1e-12)
    np.testing.assert_allclose(face.mesh(face.default_controls(1))[0, face.joint_vertices], rest)


def test_autodiff_and_finite_difference_jacobians_agree(face):
    rng = np.random.default_rng(7)
    lo, hi = face.controls.lower, face.controls.upper
    Y = lo + (hi - lo) * rng.uniform(0.05, 0.95, size=(4, face.n_controls))  # inside the clamps
    Y[0] = face.controls.defaults  # sliders at their lower ends: the clamp's gradient is 1/2 there
    J_fd = jacobian(face, Y, method="finite_difference")
    J_ad = jacobian(face, Y, method="autodiff")
    assert J_ad.shape == (4, 18, 49)
    relative = np.linalg.norm(J_fd - J_ad) / np.linalg.norm(J_ad)
    assert relative < 1e-4
    assert np.linalg.matrix_rank(J_ad[0], tol=1e-6) <= 18  # many controls, few landmarks


def test_sliders_are_clamped_to_their_range(face):
    at_top = face.evaluate(_pose(face, mouth_smile_l=1.0))
    beyond = face.evaluate(_pose(face, mouth_smile_l=2.5))
    np.testing.assert_allclose(beyond, at_top)
    below = face.evaluate(_pose(face, mouth_smile_l=-1.0))
    np.testing.assert_allclose(below, face.evaluate(face.controls.defaults))
    half = face.evaluate(_pose(face, mouth_smile_l=0.5))
    corner = LANDMARKS.index("mouth_corner_l")
    rest = face.evaluate(face.controls.defaults)
    assert at_top[corner, 1] - rest[corner, 1] > 0.3  # the corner goes up (cm)
    assert half[corner, 1] - rest[corner, 1] == pytest.approx(
        0.5 * (at_top[corner, 1] - rest[corner, 1])
    )


def test_left_shapes_mirror_right_shapes(face):
    mirror = np.array([-1.0, 1.0, 1.0])
    swap = [
        LANDMARKS.index(n)
        for n in ["brow_r", "brow_l", "mouth_corner_r", "mouth_corner_l", "upper_lip", "chin"]
    ]
    for name in ("brow_inner_up", "mouth_smile", "cheek_puff", "mouth_stretch"):
        left = face.evaluate(_pose(face, **{f"{name}_l": 1.0}))
        right = face.evaluate(_pose(face, **{f"{name}_r": 1.0}))
        cog = face.pose(face.controls.defaults).cog
        # equal up to the triangulation, whose quad diagonals are not mirror images (cm)
        np.testing.assert_allclose(((left + cog) * mirror)[swap], right + cog, atol=0.01)


def test_corrective_is_active_only_when_both_drivers_are(face):
    # the same face without its corrective shapes
    model = face.model
    silent = CombinationShapes(
        [
            CombinationSpec(
                n,
                tuple(np.array([*model.shapes.names, "jaw_open"])[d]),
                np.zeros_like(model.correctives.deltas[0]),
            )
            for n, d in zip(model.correctives.names, model.correctives.driver_index, strict=True)
        ],
        [*model.shapes.names, "jaw_open"],
        face.n_vertices,
    )
    plain = FaceRig(dataclasses.replace(model, correctives=silent))
    corner = face.joint_vertices[LANDMARKS.index("mouth_corner_l")]
    poses = {
        "jaw only": _pose(face, jaw__rx=JAW_OPEN_FULL),
        "smile only": _pose(face, mouth_smile_l=1.0),
        "both": _pose(face, jaw__rx=JAW_OPEN_FULL, mouth_smile_l=1.0),
    }
    effect = {
        k: np.linalg.norm(face.mesh(y)[corner] - plain.mesh(y)[corner]) for k, y in poses.items()
    }
    assert effect["jaw only"] == 0.0 and effect["smile only"] == 0.0
    assert effect["both"] > 0.2  # cm
    # and the map is nonlinear: the combined pose is not the sum of the single ones
    rest = face.evaluate(face.controls.defaults)
    combined = face.evaluate(poses["both"])
    summed = face.evaluate(poses["jaw only"]) + face.evaluate(poses["smile only"]) - rest
    assert np.abs(combined - summed).max() > 0.2


def test_jaw_moves_the_chin_not_the_brows(face):
    rest = face.evaluate(face.controls.defaults)
    open_ = face.evaluate(_pose(face, jaw__rx=0.4))
    moved = np.linalg.norm(open_ - rest, axis=1)
    assert moved[LANDMARKS.index("chin")] > 2.0  # cm
    assert moved[LANDMARKS.index("brow_l")] == 0.0 and moved[LANDMARKS.index("brow_r")] == 0.0
    assert open_[LANDMARKS.index("chin"), 1] < rest[LANDMARKS.index("chin"), 1]  # it drops
    forward = face.evaluate(_pose(face, jaw__tz=0.5))
    assert forward[LANDMARKS.index("chin"), 2] - rest[LANDMARKS.index("chin"), 2] == pytest.approx(
        0.5, abs=0.05
    )


def test_array_types_round_trip(face):
    Y = face.default_controls(3)
    out32 = face.evaluate(Y.astype(np.float32))
    assert isinstance(out32, np.ndarray) and out32.dtype == np.float32 and out32.shape == (3, 6, 3)
    one = face.evaluate(Y[0])
    assert one.shape == (6, 3)
    Yt = torch.tensor(_pose(face, mouth_smile_l=0.5, jaw__rx=0.2)[None], requires_grad=True)
    X = face.evaluate(Yt)
    assert isinstance(X, torch.Tensor) and X.dtype == torch.float64
    X.sum().backward()
    assert Yt.grad is not None and float(Yt.grad.abs().sum()) > 0


def test_bad_input_is_rejected_by_the_base_class(face):
    with pytest.raises(RigInputError, match=r"expected controls of shape \(N, 49\)"):
        face.evaluate(np.zeros((2, 48)))
    bad = face.default_controls(2)
    bad[1, face.controls.index("brow_down_l")] = np.nan
    with pytest.raises(RigInputError, match="brow_down_l"):
        face.evaluate(bad)


def test_render_writes_a_png_with_the_landmarks(face, tmp_path):
    from PIL import Image

    from rigmap.viz.mesh import render_mesh_views

    out = render_mesh_views(face, face.controls.defaults, tmp_path / "face.png", pixels=90)
    assert out.exists() and [p.name for p in tmp_path.iterdir()] == ["face.png"]
    image = np.asarray(Image.open(out).convert("RGB")).astype(float)
    reddish = (image[..., 0] > 200) & (image[..., 1] < 60) & (image[..., 2] < 60)
    assert reddish.sum() > 20  # the landmark dots are drawn
