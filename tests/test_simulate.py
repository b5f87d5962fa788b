"""Fig. 9's mapping without Blender: the teeth-in-body counter, a rig-posed input mapped back
onto the squirrel through `rigmap simulate input=...`, bad inputs refused in one line, the
soft body's springs and the report's section (tests/test_simulate_blender.py runs Blender).

A small squirrel project (its train corpus and poses, as the animate and pose stages write
them) lives in a temporary folder; the input is a test clip's frames, posed by the rig itself
and written as the simulation's file, so the mapping has a known answer: error near zero.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rigmap.cli import main
from rigmap.simulation.interpenetration import inside, teeth_inside_body, winding_numbers
from rigmap.simulation.sim_file import write_simulation
from rigmap.simulation.soft_body import Scenario, SimulationError, blender_scenario, soft_body

SMALL_MODEL = ["budget.gpr_points=120", "budget.length_scales=3", "budget.cv_splits=2"]


@pytest.fixture(scope="module")
def squirrel():
    from rigmap.rigs import load

    with load("squirrel") as rig:
        yield rig


def cube(half: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed cube of 12 outward triangles around the origin."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return corners.astype(np.float64), np.array(triangles)


# --- the interpenetration counter ----------------------------------------------------------
def test_winding_number_is_one_inside_a_closed_mesh_and_zero_outside():
    vertices, triangles = cube()
    points = np.array([[0, 0, 0], [0.9, -0.9, 0.5], [1.1, 0, 0], [0, 5, 0], [-0.99, 0.99, -0.99]])
    numbers = winding_numbers(points, vertices, triangles)
    np.testing.assert_allclose(np.abs(numbers), [1, 1, 0, 0, 1], atol=1e-9)
    assert inside(points, vertices, triangles).tolist() == [True, True, False, False, True]
    # the triangles' orientation does not matter
    assert inside(points, vertices, triangles[:, ::-1]).tolist() == [True, True, False, False, True]


def test_teeth_counted_inside_the_body_only_when_they_are(squirrel):
    rest = np.asarray(squirrel.world_vertices(squirrel.default_controls(1)))
    assert teeth_inside_body(squirrel, rest).tolist() == [0]  # the rest pose: teeth outside
    body = squirrel.body_vertices
    chest = rest[0, body].mean(axis=0)  # inside the body's closed surface
    pushed = rest.copy()
    teeth = np.asarray(squirrel.teeth_vertices)
    pushed[0, teeth[:5]] = chest + 0.1 * np.arange(5)[:, None]
    pushed[0, teeth[5]] = chest + np.array([0.0, 0.0, 50.0])  # far in front: still outside
    assert teeth_inside_body(squirrel, np.concatenate([rest, pushed])).tolist() == [0, 5]


def test_the_rigs_own_poses_keep_the_teeth_out_where_the_neck_bends(squirrel):
    """The collision corrective's point (Fig. 9): the head curled onto the chest."""
    Y = squirrel.default_controls(3)
    for row, bend in enumerate((1.2, 1.5, 1.8)):
        Y[row, squirrel.controls.index("neck.bend")] = bend
        Y[row, squirrel.controls.index("head.rx")] = 0.6
    meshes = np.asarray(squirrel.world_vertices(Y))
    assert teeth_inside_body(squirrel, meshes).tolist() == [0, 0, 0]


# --- the soft body's setup (what Blender is sent) -----------------------------------------
def test_soft_body_ties_every_part_and_pins_the_feet(squirrel):
    scenario = Scenario(seed=0)
    body = soft_body(squirrel, scenario)
    assert (body.springs[:, 0] < body.springs[:, 1]).all()
    assert len(np.unique(body.springs, axis=0)) == len(body.springs)
    for part, vertices in squirrel.part_vertices.items():
        if part != "body":  # each part reaches another part through its springs
            mine = np.isin(body.springs, vertices)
            assert (mine[:, 0] ^ mine[:, 1]).any(), part
    rest = np.asarray(squirrel.world_vertices(squirrel.default_controls(1)))[0]
    assert (rest[body.pinned, 1] < scenario.pin_below_cm).all() and len(body.pinned) > 10
    again = soft_body(squirrel, Scenario(seed=0))
    np.testing.assert_array_equal(again.springs, body.springs)  # from the seed only
    assert not np.array_equal(soft_body(squirrel, Scenario(seed=1)).springs, body.springs)
    sent = blender_scenario(scenario)
    assert sent["drop_m"] == pytest.approx(0.3) and sent["frames"] == 96


def test_a_scenario_that_cannot_run_is_refused():
    with pytest.raises(SimulationError, match="press_start"):
        Scenario(press_start=30, press_end=32)
    with pytest.raises(SimulationError, match="frames"):
        Scenario(frames=1)


# --- the mapping, from a rig-posed input ---------------------------------------------------
@pytest.fixture(scope="module")
def project(tmp_path_factory, squirrel):
    """data/squirrel/corpus and poses (seed 0), and a test clip's frames posed by the rig."""
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("squirrel_project")
    layout = Layout(data=root / "data", models=root / "models")
    write_corpora(squirrel, layout, seed=0, fps=24, variation=1.0)
    pose_corpora(squirrel, layout, batch_size=512, progress=False)
    import pandas as pd

    test = pd.read_parquet(layout.corpus("squirrel", "test"))
    clip = test[test["clip"] == test["clip"].iloc[0]].iloc[::4][:10]
    Y = squirrel.default_controls(len(clip))
    for name in squirrel.used_controls:
        Y[:, squirrel.controls.index(name)] = clip[name].to_numpy()
    world = np.asarray(squirrel.world_vertices(Y))
    posed = write_simulation(
        root / "posed.npz", world, squirrel.joint_names, 24.0, squirrel.faces, {}
    )
    return root, posed, world


def run_simulate(root: Path, inputs: Path, out: Path, *extra: str) -> int:
    return main(
        [
            "simulate",
            f"input={inputs}",
            f"out={out}",
            f"paths.data={root / 'data'}",
            f"paths.models={root / 'models'}",
            "simulate.figure_frames=[0,5]",
            *SMALL_MODEL,
            *extra,
        ]
    )


def test_a_rig_posed_input_maps_back_with_near_zero_vertex_error(project, squirrel, tmp_path):
    root, posed, world = project
    # plain Eq. 13 (no pull toward the guess), iterated: the rig's own poses are reachable
    refine = ["simulate.settings.prior_weight=0", "simulate.settings.refine_iterations=10"]
    assert run_simulate(root, posed, tmp_path / "out", *refine) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["frames"] == len(world)
    assert summary["vertex_error_rms_cm"] < 0.1, summary["vertex_error_rms_cm"]  # of 36 cm
    assert summary["guess_vertex_error_rms_cm"] >= summary["vertex_error_rms_cm"]
    assert summary["teeth_inside_body"]["rig"]["teeth_vertex_frames_inside"] == 0
    assert summary["seconds_per_frame"] > 0 and summary["subset"]["vertices"] == 227
    import pandas as pd

    controls = pd.read_parquet(tmp_path / "out" / "controls.parquet")
    assert list(controls.columns) == ["frame", *squirrel.control_names]
    assert len(controls) == len(world)
    assert (tmp_path / "out" / "simulate_squirrel.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    ("fault", "message"),
    [
        ("vertices", "1124 vertices per frame, rig 'squirrel' has 1125"),
        ("nan", "is nan at frame 2"),
    ],
)
def test_bad_inputs_are_refused_with_one_line(project, squirrel, tmp_path, capsys, fault, message):
    root, _, world = project
    positions = world[:4].copy()
    names = list(squirrel.joint_names)
    if fault == "vertices":
        positions, names = positions[:, 1:], names[1:]
    else:
        positions[2, 17, 1] = np.nan
    bad = write_simulation(tmp_path / "bad.npz", positions, names, 24.0, squirrel.faces, {})
    assert run_simulate(root, bad, tmp_path / "out") == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1
    assert error.startswith("rigmap: error: simulate: ") and message in error
    assert not (tmp_path / "out" / "summary.json").exists()
