"""The squirrel's soft body in Blender (Fig. 9): deterministic for a seed, and it moves.

A small, quick scenario (18 frames, a short drop, an early press, fewer solver steps) run
twice in fresh Blender workers: the vertices agree to 1e-6 cm; another seed (another strut
layout and push direction) gives other vertices.
"""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.simulation.soft_body import Cloth, Scenario, simulate_soft_body

pytestmark = [pytest.mark.blender]

QUICK = dict(
    frames=18,
    drop_cm=10.0,
    press_start=6,
    press_end=16,
    press_ramp=3,
    push_start=8,
    push_end=16,
    cloth=Cloth(quality=4),
)


@pytest.fixture(scope="module")
def squirrel():
    from rigmap.rigs import load

    with load("squirrel") as rig:
        yield rig


@pytest.fixture(scope="module")
def first(squirrel):
    return simulate_soft_body(squirrel, Scenario(seed=3, **QUICK))


def test_the_simulation_is_deterministic_for_a_seed(squirrel, first):
    again = simulate_soft_body(squirrel, Scenario(seed=3, **QUICK))
    assert first.vertices.shape == (18, squirrel.n_vertices, 3)
    np.testing.assert_allclose(again.vertices, first.vertices, rtol=0, atol=1e-6)
    other = simulate_soft_body(squirrel, Scenario(seed=4, **QUICK))
    assert np.abs(other.vertices - first.vertices).max() > 1e-3


def test_the_squirrel_falls_lands_and_deforms(squirrel, first):
    rest = np.asarray(squirrel.world_vertices(squirrel.default_controls(1)))[0]
    vertices = first.vertices
    dropped = rest + np.array([0.0, 10.0, 0.0])  # cm, Y up
    np.testing.assert_allclose(vertices[0], dropped, atol=1e-4)
    assert vertices[-1][:, 1].min() == pytest.approx(rest[:, 1].min(), abs=0.5)  # on the ground
    moved = vertices[-1] - vertices[-1].mean(axis=0) - (rest - rest.mean(axis=0))
    assert np.linalg.norm(moved, axis=1).max() > 0.5  # a soft body, not a rigid one
    assert first.info["landing_frame"] == 5 and first.info["pinned"] > 10
