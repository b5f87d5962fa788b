"""The mesh deformers behind the face and squirrel rigs, each checked on its own."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rigmap.rigs.engine.transforms import Transform, axis_rotation
from rigmap.rigs.mesh.blendshapes import (
    Blendshapes,
    CombinationShapes,
    CombinationSpec,
    ShapeSpec,
)
from rigmap.rigs.mesh.collision import CollisionSink, rounded_ramp
from rigmap.rigs.mesh.geometry import (
    ellipsoid_point,
    signed_volume,
    superellipsoid_point,
    surface_of_revolution,
    swept_tube,
)
from rigmap.rigs.mesh.lattice import BernsteinLattice, deform
from rigmap.rigs.mesh.lattice_deformers import bend, squash_stretch, twist
from rigmap.rigs.mesh.proximity import distances_to_mesh, signed_distances, winding_numbers
from rigmap.rigs.mesh.skinning import Bone, LinearBlendSkin, Skeleton, skinning_transforms


def _edges_shared_twice(faces: np.ndarray) -> bool:
    """Watertight and consistently wound: each directed edge once, its reverse once."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    forward = {tuple(e) for e in directed}
    return len(forward) == len(directed) and all((b, a) in forward for a, b in forward)


# --- geometry -----------------------------------------------------------------------
def test_closed_grid_primitives_are_watertight_and_outward():
    sphere = surface_of_revolution(
        ellipsoid_point((1, 2, 3), (2.0, 3.0, 4.0)), np.linspace(0.05, np.pi - 0.05, 60), 64
    )
    assert _edges_shared_twice(sphere.faces)
    volume = signed_volume(sphere.vertices, sphere.faces)
    assert volume == pytest.approx(4 / 3 * np.pi * 2 * 3 * 4, rel=0.02)

    box = surface_of_revolution(
        superellipsoid_point((0, 0, 0), (1, 1, 1), 0.1), np.linspace(0.1, np.pi - 0.1, 9), 16
    )
    assert _edges_shared_twice(box.faces)
    assert signed_volume(box.vertices, box.faces) > 4.0  # nearly the 2 x 2 x 2 cube, not a ball

    curve = np.stack([np.zeros(12), np.linspace(0, 10, 12), np.sin(np.linspace(0, 3, 12))], 1)
    tube = swept_tube(curve, np.full(12, 1.0), 10)
    assert _edges_shared_twice(tube.faces)
    assert signed_volume(tube.vertices, tube.faces) > 0


# --- proximity ------------------------------------------------------------------------
def test_winding_numbers_and_distances_on_a_sphere():
    sphere = surface_of_revolution(
        ellipsoid_point((0, 0, 0), (5.0, 5.0, 5.0)), np.linspace(0.04, np.pi - 0.04, 48), 48
    )
    points = np.array([[0, 0, 0], [1, 2, -1], [0, 7, 0], [9, 0, 0], [0, 0, -4.5]], float)
    w = winding_numbers(points, sphere.vertices, sphere.faces)
    np.testing.assert_allclose(w, [1, 1, 0, 0, 1], atol=1e-6)
    d = distances_to_mesh(points, sphere.vertices, sphere.faces)
    expected = np.abs(np.linalg.norm(points, axis=1) - 5.0)
    np.testing.assert_allclose(d, expected, atol=0.05)  # the mesh is a little inside the sphere
    s = signed_distances(points, sphere.vertices, sphere.faces)
    assert np.all(np.sign(s) == [-1, -1, 1, 1, -1])


def test_point_triangle_distance_matches_dense_sampling():
    rng = np.random.default_rng(3)
    triangle = rng.normal(size=(3, 3))
    faces = np.array([[0, 1, 2]])
    u, v = np.meshgrid(np.linspace(0, 1, 301), np.linspace(0, 1, 301))
    keep = u + v <= 1
    samples = (
        triangle[0]
        + u[keep, None] * (triangle[1] - triangle[0])
        + v[keep, None] * (triangle[2] - triangle[0])
    )
    points = rng.normal(scale=2.0, size=(40, 3))
    brute = np.linalg.norm(points[:, None] - samples[None], axis=2).min(axis=1)
    exact = distances_to_mesh(points, triangle, faces)
    assert np.all(exact <= brute + 1e-12)
    np.testing.assert_allclose(exact, brute, atol=0.02)


# --- lattice -------------------------------------------------------------------------
def test_untouched_lattice_is_the_identity_and_weights_sum_to_one():
    lattice = BernsteinLattice((-2, 0, -1), (2, 5, 3), degrees=(2, 4, 3))
    points = np.random.default_rng(0).uniform((-2, 0, -1), (2, 5, 3), size=(50, 3))
    W = lattice.weights(points)
    np.testing.assert_allclose(W.sum(axis=1), 1.0, atol=1e-12)
    moved = deform(torch.as_tensor(W), torch.as_tensor(lattice.rest_control_points)[None])
    np.testing.assert_allclose(moved[0].numpy(), points, atol=1e-12)


def test_lattice_jacobian_weights_match_finite_differences():
    lattice = BernsteinLattice((-2, 0, -1), (2, 5, 3), degrees=(2, 5, 2))
    rng = np.random.default_rng(1)
    control = lattice.rest_control_points + rng.normal(
        scale=0.3, size=(lattice.n_control_points, 3)
    )
    point = np.array([[0.3, 2.2, 0.9]])
    analytic = np.einsum("ak,kc->ca", lattice.jacobian_weights(point)[0], control)
    h = 1e-6
    numeric = np.stack(
        [
            (lattice.weights(point + h * e) - lattice.weights(point - h * e))[0] @ control / (2 * h)
            for e in np.eye(3)
        ],
        axis=1,
    )
    np.testing.assert_allclose(analytic, numeric, atol=1e-7)


def test_bend_keeps_the_neutral_line_length_and_reaches_the_angle():
    heights = torch.linspace(0, 10, 101, dtype=torch.float64)
    line = torch.stack([torch.zeros(101), heights, torch.zeros(101)], 1).to(torch.float64)[None]
    angle = torch.tensor([1.2], dtype=torch.float64)
    bent = bend(line, angle, base=0.0, length=10.0, axis="z", center=0.0)[0]
    steps = torch.linalg.vector_norm(bent[1:] - bent[:-1], dim=1)
    assert float(steps.sum()) == pytest.approx(10.0, rel=1e-4)
    tangent = bent[-1] - bent[-2]
    assert float(torch.atan2(tangent[2], tangent[1])) == pytest.approx(1.2, abs=0.01)
    assert float(bent[-1, 2]) > 3.0  # a positive angle bends towards +z (forward)
    flat = bend(
        line, torch.zeros(1, dtype=torch.float64), base=0.0, length=10.0, axis="z", center=0
    )
    torch.testing.assert_close(flat, line)


def test_twist_and_squash():
    top = torch.tensor([[[1.0, 10.0, 0.0], [0.0, 10.0, 1.0]]], dtype=torch.float64)
    turned = twist(
        top,
        torch.tensor([np.pi / 2], dtype=torch.float64),
        base=0.0,
        length=10.0,
        center_xz=(0.0, 0.0),
    )
    torch.testing.assert_close(turned[0, 1], torch.tensor([1.0, 10.0, 0.0], dtype=torch.float64))
    box = torch.tensor([[[1.0, 2.0, 1.0]]], dtype=torch.float64)
    squashed = squash_stretch(
        box, torch.tensor([-0.4], dtype=torch.float64), base=0.0, center_xz=(0.0, 0.0)
    )[0, 0]
    assert float(squashed.prod()) == pytest.approx(2.0)  # x * y * z volume preserved
    assert float(squashed[1]) < 2.0


# --- blendshapes ---------------------------------------------------------------------
def test_blendshape_weights_are_clamped_to_their_range():
    deltas = np.zeros((4, 3))
    deltas[1] = (0.0, 1.0, 0.0)
    shapes = Blendshapes([ShapeSpec("up", deltas, 0.0, 1.0), ShapeSpec("shift", deltas, -1, 1)], 4)
    values = torch.tensor([[-0.5, -2.0], [0.25, 0.5], [3.0, 1.5]], dtype=torch.float64)
    np.testing.assert_allclose(shapes.clamp(values).numpy(), [[0, -1], [0.25, 0.5], [1, 1]])
    offsets = shapes.offsets(shapes.clamp(values)[:, :1], torch.as_tensor(shapes.deltas[:1]))
    np.testing.assert_allclose(offsets[:, 1, 1].numpy(), [0.0, 0.25, 1.0])


def test_combination_weight_is_the_product_of_its_drivers():
    combos = CombinationShapes(
        [CombinationSpec("ab", ("a", "b"), np.ones((2, 3)))], ["a", "b", "c"], 2
    )
    drivers = torch.tensor(
        [[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 0.0], [0.5, 0.4, 0.0]], dtype=torch.float64
    )
    np.testing.assert_allclose(combos.weights(drivers)[:, 0].numpy(), [0, 0, 1, 0.2])
    with pytest.raises(ValueError, match="unknown drivers"):
        CombinationShapes([CombinationSpec("x", ("a", "zz"), np.ones((2, 3)))], ["a"], 2)


# --- skinning --------------------------------------------------------------------------
def test_skinning_moves_fully_weighted_vertices_rigidly_and_blends_between():
    skeleton = Skeleton([Bone("root", None, (0, 0, 0)), Bone("arm", "root", (0, 1, 0))])
    rest = [
        Transform(torch.eye(3, dtype=torch.float64)[None], torch.as_tensor(p[None]))
        for p in skeleton.pivots
    ]
    R = axis_rotation(torch.tensor([np.pi / 2], dtype=torch.float64), "z")
    posed = skeleton.forward_kinematics(rest, {"arm": R})
    skins = skinning_transforms(rest, posed)
    weights = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]])
    skin = LinearBlendSkin(weights, skeleton.names)
    vertices = torch.tensor(
        [[[0.0, 0.5, 0.0], [0.0, 2.0, 0.0], [0.0, 2.0, 0.0]]], dtype=torch.float64
    )
    out = skin.apply(vertices, skins, torch.as_tensor(weights))[0].numpy()
    np.testing.assert_allclose(out[0], [0.0, 0.5, 0.0], atol=1e-12)  # root: unmoved
    np.testing.assert_allclose(out[1], [-1.0, 1.0, 0.0], atol=1e-12)  # turned about (0, 1, 0)
    np.testing.assert_allclose(out[2], [-0.5, 1.5, 0.0], atol=1e-12)  # LBS average
    with pytest.raises(ValueError, match="sum to"):
        LinearBlendSkin(np.array([[0.7, 0.2]]), skeleton.names)


# --- collision corrective ------------------------------------------------------------------
def _plate_and_point(height: float):
    """A flat 9 x 9 grid at z = 0 (the sinking region, sink direction -z) and a point above."""
    xs, ys = np.meshgrid(np.linspace(-4, 4, 9), np.linspace(-4, 4, 9))
    plate = np.stack([xs.ravel(), ys.ravel(), np.zeros(81)], 1)
    vertices = np.concatenate([plate, [[0.3, -0.2, height]]])
    sink = CollisionSink(vertices, np.arange(81), np.ones(81), np.array([81]), margin=0.5)
    return sink, torch.as_tensor(vertices)[None]


def test_collision_sink_pushes_the_region_behind_the_point_and_is_exactly_zero_far_away():
    direction = torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64).expand(1, 81, 3)
    weight = torch.ones(81, dtype=torch.float64)
    for height in (0.3, -0.4, -2.0):  # nearly touching, 0.4 cm through, 2 cm through
        sink, vertices = _plate_and_point(height)
        moved = vertices[0, :81] + sink.push(vertices, direction, weight)[0]
        near = torch.linalg.vector_norm(moved[:, :2] - torch.tensor([0.3, -0.2]), dim=1) < 2.5
        assert float(moved[near, 2].max()) <= height - 0.5 + 1e-9  # behind it by the margin
    sink, vertices = _plate_and_point(3.0)
    assert float(sink.push(vertices, direction, weight).abs().max()) == 0.0


def test_rounded_ramp_is_never_below_relu_and_exact_outside_its_corner():
    x = torch.linspace(-1, 1, 401, dtype=torch.float64)
    y = rounded_ramp(x, 0.25)
    assert bool(torch.all(y >= torch.clamp(x, min=0)))
    assert bool(torch.all(y[x <= -0.25] == 0))
    torch.testing.assert_close(y[x >= 0.25], x[x >= 0.25])
