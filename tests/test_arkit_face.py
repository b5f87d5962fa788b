"""The ARKit face: the built-in face's mesh driven by ARKit's 52 weights (issue #41, item 2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from rigmap.latent.live_link import BLENDSHAPES, arkit_name, live_link_columns, read_take
from rigmap.rigs import load

FACE_TAKES = Path(__file__).resolve().parents[2] / "shared" / "face"


@pytest.fixture(scope="module")
def arkit():
    return load("arkit_face")


@pytest.fixture(scope="module")
def face():
    return load("face")


def _weights(rig, **values) -> np.ndarray:
    y = np.zeros(len(rig.controls))
    for name, value in values.items():
        y[rig.controls.index(name)] = value
    return y[None]


def _moved(rig, **values) -> np.ndarray:
    """Each vertex's displacement (cm) from the rest mesh under ``values``."""
    rest = rig.mesh(np.zeros((1, len(rig.controls))))[0]
    return rig.mesh(_weights(rig, **values))[0] - rest


def test_controls_are_arkits_weights_in_live_link_order(arkit):
    assert arkit.control_names == [arkit_name(column) for column in BLENDSHAPES]
    assert live_link_columns(arkit.control_names) == BLENDSHAPES
    assert np.all(arkit.controls.lower == 0) and np.all(arkit.controls.upper == 1)
    unused = [c.name for c in arkit.controls if not c.used]
    looks = ["eyeLookInLeft", "eyeLookOutLeft", "eyeLookInRight", "eyeLookOutRight"]
    assert sorted(unused) == sorted([*looks, "tongueOut"])  # no eyeball, no tongue
    assert arkit.joint_names == load("face").joint_names


def test_the_mesh_is_the_faces_mesh_at_the_mapped_sliders(arkit, face):
    rng = np.random.default_rng(3)
    weights = rng.uniform(0, 1, size=(5, len(arkit.controls)))
    np.testing.assert_allclose(
        arkit.mesh(weights), face.mesh(arkit.face_values(weights)), atol=1e-12
    )
    np.testing.assert_allclose(
        arkit.mesh(np.zeros((1, 52))), face.mesh(face.controls.defaults[None])
    )
    np.testing.assert_allclose(
        arkit.pose(weights).positions, face.pose(arkit.face_values(weights)).positions, atol=1e-12
    )


def test_each_shape_moves_what_its_name_says(arkit):
    x = arkit.rest_vertices[:, 0]
    blink = _moved(arkit, eyeBlinkLeft=1.0)  # the character's (the performer's) left lid
    assert np.abs(blink[x > 1.0]).max() > 0.3 and np.abs(blink[x < -1.0]).max() < 0.01
    assert blink[x > 1.0, 1].min() < -0.3  # the upper lid comes down
    landmarks = dict(zip(arkit.joint_names, range(6), strict=True))
    rest = arkit.pose(np.zeros((1, 52))).positions[0]

    def landmark_shift(name, **values):
        return (
            arkit.pose(_weights(arkit, **values)).positions[0, landmarks[name]]
            - rest[landmarks[name]]
        )

    assert landmark_shift("chin", jawOpen=1.0)[1] < -1.0  # the chin drops
    assert (
        landmark_shift("chin", jawLeft=1.0)[0]
        > 0.1
        > -0.1
        > landmark_shift("chin", jawRight=1.0)[0]
    )
    assert landmark_shift("mouth_corner_l", mouthSmileLeft=1.0)[1] > 0.3  # corner up
    assert np.abs(landmark_shift("mouth_corner_r", mouthSmileLeft=1.0)).max() < 0.01
    assert landmark_shift("mouth_corner_l", mouthLeft=1.0)[0] > 0.2  # toward +x
    assert (
        landmark_shift("brow_l", browInnerUp=1.0)[1] > 0
        and landmark_shift("brow_r", browInnerUp=1.0)[1] > 0
    )
    for still in ("eyeLookInLeft", "eyeLookOutRight", "tongueOut"):
        assert np.abs(_moved(arkit, **{still: 1.0})).max() == 0.0


def test_gradients_flow_from_the_landmarks_to_the_weights(arkit):
    weights = torch.full((2, 52), 0.3, dtype=torch.float64, requires_grad=True)
    arkit.pose(weights).positions.sum().backward()
    grad = weights.grad.numpy()
    assert np.isfinite(grad).all()
    assert np.abs(grad[:, arkit.controls.index("jawOpen")]).min() > 0
    assert np.all(grad[:, arkit.controls.index("tongueOut")] == 0)


def test_a_captured_take_drives_the_face(arkit):
    """A shared Live Link Face take's curves, resampled, posed on the rig frame by frame."""
    take = read_take(FACE_TAKES / "alex_rom_3.csv")
    segment = take.segments()[0]
    curves = segment.values[:, [take.columns.index(c) for c in BLENDSHAPES]]
    vertices = arkit.mesh(np.clip(curves[::10], 0.0, 1.0))
    assert np.isfinite(vertices).all()
    travel = np.linalg.norm(vertices - vertices.mean(axis=0), axis=2).max(axis=0)
    assert travel.max() > 1.0  # the range-of-motion take moves the jaw and lips by cm
    assert np.median(travel) < 0.5  # the crown and the back of the head barely move
