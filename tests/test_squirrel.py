"""The built-in squirrel mesh rig: 36 controls -> 1 125 vertices (Table 3, Fig. 9)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rigmap.refine import jacobian
from rigmap.rigs import RigInputError, load
from rigmap.rigs.characters.squirrel import build_squirrel
from rigmap.rigs.mesh.proximity import signed_distances

NECK_SWEEP = np.linspace(-0.6, 1.8, 13)  # neck.bend over its whole soft range (radians)
# other controls held during the sweep: rest, head tilted down, body squashed, body bent
SWEEP_SETTINGS = {
    "rest": {},
    "head down": {"head.rx": 0.6},
    "squashed": {"body.squash": -0.4, "head.rx": 0.6},
    "bent over": {"body.bend_forward": 0.9, "head.rx": 0.3},
}


@pytest.fixture(scope="module")
def squirrel():
    return load("squirrel")


@pytest.fixture(scope="module")
def squirrel_without_corrective():
    return build_squirrel(neck_collision=False)


def _poses(rig, n: int, **values) -> np.ndarray:
    Y = rig.default_controls(n)
    for name, value in values.items():
        Y[:, rig.controls.index(name)] = value
    return Y


def _teeth_clearance(rig, Y) -> np.ndarray:
    """Per pose: smallest signed distance (cm) of a tooth vertex to the deformed body surface.

    Negative means a tooth vertex is inside the body (winding number > 1/2).
    """
    meshes = rig.mesh(Y)
    return np.array(
        [signed_distances(m[rig.teeth_vertices], m, rig.body_faces).min() for m in meshes]
    )


def test_describe_counts(squirrel):
    assert len(squirrel.controls) >= 30
    assert squirrel.n_joints >= 1000 and squirrel.n_joints == squirrel.n_vertices == 1125
    assert squirrel.joint_names[:2] == ["v0000", "v0001"]
    assert squirrel.parents is None and squirrel.differentiable
    assert squirrel.controls.summary()["used"] == len(squirrel.controls) == 36
    parts = set(squirrel.part_vertices)
    assert {"body", "head", "tail", "ear_l", "ear_r", "tooth_l", "tooth_r"} <= parts


def test_every_part_is_closed(squirrel):
    faces = squirrel.faces
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = {tuple(e) for e in directed}
    assert len(edges) == len(directed)
    assert all((b, a) in edges for a, b in edges)  # each edge shared by two faces, opposite ways


def test_rest_pose_is_the_rest_mesh_and_the_cog_is_the_body_centre(squirrel):
    pose = squirrel.pose(squirrel.default_controls(1))
    np.testing.assert_allclose(pose.cog[0], [0.0, 13.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(pose.positions[0] + pose.cog[0], squirrel.rest_vertices, atol=1e-9)


def test_placement_moves_the_cog_not_the_cog_relative_vertices(squirrel):
    base = squirrel.pose(_poses(squirrel, 1, **{"neck.bend": 0.5}))
    moved = squirrel.pose(_poses(squirrel, 1, **{"neck.bend": 0.5, "root.tx": 12.0, "root.tz": -3}))
    np.testing.assert_allclose(moved.positions, base.positions, atol=1e-9)
    np.testing.assert_allclose(moved.cog - base.cog, [[12.0, 0.0, -3.0]], atol=1e-9)
    turned = squirrel.pose(_poses(squirrel, 1, **{"neck.bend": 0.5, "root.ry": np.pi / 2}))
    np.testing.assert_allclose(turned.positions[0, :, 2], -base.positions[0, :, 0], atol=1e-9)


def test_lattice_squash_keeps_the_feet_down_and_lowers_the_head(squirrel):
    rest = (
        squirrel.mesh(squirrel.default_controls(1)) + squirrel.pose(squirrel.controls.defaults).cog
    )
    Y = _poses(squirrel, 1, **{"body.squash": -0.4})
    squashed = squirrel.mesh(Y) + squirrel.pose(Y).cog
    head = squirrel.part_vertices["head"]
    assert squashed[0, head, 1].max() < rest[0, head, 1].max() - 5.0  # cm lower
    assert abs(squashed[0, :, 1].min() - rest[0, :, 1].min()) < 0.3  # the ground stays
    width = np.ptp(squashed[0, squirrel.body_vertices, 0])
    assert width > np.ptp(rest[0, squirrel.body_vertices, 0]) * 1.1  # and it bulges


# torch.func's forward mode scripts a few helpers on first use (a torch-internal deprecation)
@pytest.mark.filterwarnings("ignore:`torch.jit.script` is deprecated:DeprecationWarning")
def test_autodiff_and_finite_difference_jacobians_agree(squirrel):
    rng = np.random.default_rng(11)
    lo, hi = squirrel.controls.lower, squirrel.controls.upper
    Y = lo + (hi - lo) * rng.uniform(0.1, 0.9, size=(2, squirrel.n_controls))
    Y[1, squirrel.controls.index("neck.bend")] = 1.6  # teeth against the chest: corrective on
    Y[1, squirrel.controls.index("head.rx")] = 0.4
    J_fd = jacobian(squirrel, Y, method="finite_difference")
    # forward mode: 36 tangents instead of 3 375 cotangents (rigmap.refine's reverse mode
    # would need gigabytes here); same autodiff through the same torch code
    used = torch.as_tensor(squirrel.controls.used_indices)
    full = torch.as_tensor(Y)

    def summed_positions(y_used):
        x = squirrel.evaluate(full.index_copy(1, used, y_used))
        return x.reshape(len(Y), -1).sum(0)

    J_ad = torch.func.jacfwd(summed_positions)(full[:, used]).permute(1, 0, 2).numpy()
    assert J_ad.shape == J_fd.shape == (2, 3375, 36)
    relative = np.linalg.norm(J_fd - J_ad) / np.linalg.norm(J_ad)
    assert relative < 1e-4


@pytest.mark.parametrize("setting", list(SWEEP_SETTINGS))
def test_teeth_stay_outside_the_body_over_the_neck_bend_sweep(
    setting, squirrel, squirrel_without_corrective
):
    Y = _poses(squirrel, len(NECK_SWEEP), **SWEEP_SETTINGS[setting])
    Y[:, squirrel.controls.index("neck.bend")] = NECK_SWEEP
    with_corrective = _teeth_clearance(squirrel, Y)
    without = _teeth_clearance(squirrel_without_corrective, Y)
    assert with_corrective.min() > 0.2  # cm: every tooth vertex outside the body, with room
    # the measurement can see a collision: without the corrective the teeth go in
    assert without.min() < -0.5
    # and it acts only near contact: far from the body the two rigs agree
    far = without > 1.5
    assert far.any()
    np.testing.assert_allclose(with_corrective[far], without[far])


def test_corrective_is_exactly_off_away_from_contact(squirrel, squirrel_without_corrective):
    Y = _poses(squirrel, 3, **{"neck.bend": 0.3, "tail.curl": 0.8})
    Y[1, squirrel.controls.index("body.twist")] = 0.5
    Y[2, squirrel.controls.index("head.ry")] = 0.8
    np.testing.assert_array_equal(squirrel.mesh(Y), squirrel_without_corrective.mesh(Y))


def test_shape_sliders_are_clamped(squirrel):
    full = squirrel.evaluate(_poses(squirrel, 1, **{"tail.fluff": 1.0}))
    beyond = squirrel.evaluate(_poses(squirrel, 1, **{"tail.fluff": 1.7}))
    np.testing.assert_allclose(beyond, full)
    rest = squirrel.evaluate(squirrel.default_controls(1))
    tail = squirrel.part_vertices["tail"]
    assert np.linalg.norm(full[0, tail] - rest[0, tail], axis=1).max() > 1.0  # cm


def test_array_types_round_trip(squirrel):
    Y = _poses(squirrel, 2, **{"neck.bend": 1.2})
    out32 = squirrel.evaluate(Y.astype(np.float32))
    assert out32.dtype == np.float32 and out32.shape == (2, 1125, 3)
    np.testing.assert_allclose(out32, squirrel.evaluate(Y), atol=1e-3)
    Yt = torch.tensor(Y[:1], requires_grad=True)
    X = squirrel.evaluate(Yt)
    X[:, squirrel.teeth_vertices].sum().backward()
    assert float(Yt.grad[0, squirrel.controls.index("neck.bend")].abs()) > 0


def test_bad_input_is_rejected_by_the_base_class(squirrel):
    with pytest.raises(RigInputError, match=r"expected controls of shape \(N, 36\)"):
        squirrel.evaluate(np.zeros(35))
    bad = squirrel.default_controls(1)
    bad[0, squirrel.controls.index("tail_2.ry")] = np.inf
    with pytest.raises(RigInputError, match=r"tail_2\.ry"):
        squirrel.evaluate(bad)
