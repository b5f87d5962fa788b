"""Fig. 7's path edit (issue #42 item 2): a clip looped, bent along a path, set on a terrain.

On a synthetic walker (a pelvis travelling with sway, two legs whose feet stand still in
stance and swing forward lifted): a straight path along the clip's own travel on flat
ground gives the input back; a quarter circle turns it by 90°; looping has no seam jump;
planted feet end on the terrain and do not slide; bad path and terrain files and options
are refused in one line naming them.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from rigmap.app.map_path_options import PathOptionError, path_edit_from_options
from rigmap.map.cycles import CycleError, find_cycle, local_pose, loop_cycle
from rigmap.map.path_edit import GroundPath, PathEdit, PathEditError, heading, read_path
from rigmap.map.terrain import HeightField, Procedural, TerrainError, read_height_field

NAMES = ["pelvis", "head", "thigh_l", "foot_l", "ball_l", "thigh_r", "foot_r", "ball_r"]
PARENTS = [-1, 0, 0, 2, 3, 0, 5, 6]
FEET = ["foot_l", "ball_l", "foot_r", "ball_r"]
FPS = 24.0


def walker(frames: int, period: float = 30.0, stride: float = 80.0, angle: float = 0.3):
    """World joints ``(F, 8, 3)``: the pelvis moves at stride/period per frame along
    ``angle`` (heading, rad); each foot stands for 60 % of its cycle, then swings."""
    f = np.arange(frames, dtype=float)
    speed = stride / period
    out = np.zeros((frames, len(NAMES), 3))
    forward = speed * f
    out[:, 0] = np.stack(
        [1.5 * np.sin(2 * np.pi * f / period), 95 + np.cos(4 * np.pi * f / period), forward], 1
    )
    out[:, 1] = out[:, 0] + [0, 70, 5]
    for side, (thigh, foot, ball), phase in ((1, (2, 3, 4), 0.0), (-1, (5, 6, 7), 0.5)):
        out[:, thigh] = out[:, 0] + [10 * side, -8, 0]
        cycle = (f / period + phase) % 1.0
        start = np.floor(f / period + phase)  # which stride the foot is on
        swing = np.clip((cycle - 0.6) / 0.4, 0, 1)
        z = stride * (start + swing) - stride * phase
        y = 9 + 12 * np.sin(np.pi * swing)
        out[:, foot] = np.stack([np.full(frames, 10.0 * side), y, z], 1)
        out[:, ball] = out[:, foot] + [0, -6, 14]
    c, s = np.cos(angle), np.sin(angle)
    x, z = out[..., 0].copy(), out[..., 2].copy()
    out[..., 0], out[..., 2] = c * x + s * z, -s * x + c * z
    return out + np.array([40.0, 0.0, -20.0])


def straight_path(world, points: int = 2) -> GroundPath:
    start, end = world[0, 0, [0, 2]], world[-1, 0, [0, 2]]
    t = np.linspace(0.0, 1.5, points)[:, None]
    return GroundPath(start + t * (end - start))


def quarter_circle(world, radius: float | None = None, start=(0.0, 0.0)) -> GroundPath:
    travel = np.linalg.norm(world[-1, 0, [0, 2]] - world[0, 0, [0, 2]])
    radius = radius or travel / (np.pi / 2)
    theta = np.linspace(0, np.pi / 2, 25)
    return GroundPath(
        np.stack([radius - radius * np.cos(theta), radius * np.sin(theta)], 1) + start
    )


def edit(world, path, terrain=None, loop=None):
    return PathEdit(path, terrain or Procedural("flat"), loop).apply(
        world, NAMES, PARENTS, FEET, FPS
    )


@pytest.mark.parametrize("points", [2, 7])
def test_a_straight_path_on_flat_ground_gives_the_input_back(points):
    world = walker(90)
    clip = edit(world, straight_path(world, points))
    assert clip.contacts.planted.any(axis=0).all()  # plants found, held (at rest already)
    np.testing.assert_allclose(clip.edited, world, atol=1e-6)


def test_a_quarter_circle_turns_the_heading_by_90_degrees():
    world = walker(90)
    clip = edit(world, quarter_circle(world))
    hips = clip.edited[:, 2, [0, 2]] - clip.edited[:, 5, [0, 2]]
    before = world[:, 2, [0, 2]] - world[:, 5, [0, 2]]
    turn = np.degrees(np.unwrap(heading(hips) - heading(before)))
    assert turn[0] == pytest.approx(-np.degrees(0.3), abs=2.0)  # the path starts along +Z
    assert turn[-1] - turn[0] == pytest.approx(90.0, abs=2.0)  # it walks the whole circle
    travel = np.diff(clip.edited[-10:, 0, [0, 2]], axis=0).sum(axis=0)
    assert np.degrees(heading(travel)) == pytest.approx(90.0, abs=5.0)  # ends going along +X


def test_looping_finds_the_cycle_and_keeps_the_seams_continuous():
    world = walker(75, period=29.4)  # not a whole number of frames: a plain repeat jumps
    cycle = find_cycle(world, 0, FPS)
    assert cycle.period in (29, 30)
    blended = loop_cycle(world, 0, cycle, 300, blend_frames=6)
    a, p = cycle.start, cycle.period
    source, looped = local_pose(world, 0), local_pose(blended, 0)
    naive = np.concatenate([source[a : a + p]] * 3)  # the cycle repeated with no blend
    residual = np.abs(source[a + p] - source[a]).max()
    assert residual > 0.5  # the cycle does not close by itself
    d2_source = source[a + p] - 2 * source[a + p - 1] + source[a + p - 2]
    for k in (1, 2):
        seam = k * p  # the first frame of a repeat
        d2_loop = looped[seam] - 2 * looped[seam - 1] + looped[seam - 2]
        d2_naive = naive[seam] - 2 * naive[seam - 1] + naive[seam - 2]
        assert np.abs(d2_loop - d2_source).max() < 0.3 * residual
        assert np.abs(d2_naive - d2_source).max() > 0.9 * residual
    travel = np.linalg.norm(np.diff(blended[:, 0, [0, 2]], axis=0), axis=1)
    assert travel.max() < 1.5 * np.median(travel)  # the root goes on, no jump back


def test_the_cycle_is_the_pose_returning_not_the_smallest_lag():
    """Drift (the head and hips sinking 1 cm a frame) makes every long lag worse than a short
    one; the period is still the lag where the pose returns."""
    world = walker(120, period=36)
    world[:, [1, 2, 5], 1] -= np.arange(120)[:, None]
    assert find_cycle(world, 0, FPS).period == 36
    with pytest.raises(CycleError, match="never returns"):
        find_cycle(world[:, :1] + np.arange(120)[:, None, None] ** 2 * [0.0, 1.0, 0.0], 0, FPS)


@pytest.mark.parametrize(
    "terrain", [Procedural("slope", slope_percent=12, heading_deg=30), Procedural("sine")]
)
def test_planted_feet_end_on_the_terrain_and_do_not_slide(terrain):
    world = walker(90)
    clip = PathEdit(quarter_circle(world, start=(40, -20)), terrain, loop_seconds=6.0).apply(
        world, NAMES, PARENTS, FEET, FPS
    )
    from rigmap.map.contacts import foot_skate

    assert len(clip.edited) == 144
    columns = [NAMES.index(f) for f in FEET]
    over = clip.edited[:, columns, 1] - terrain.height(
        clip.edited[:, columns, 0], clip.edited[:, columns, 2]
    )
    planted = clip.contacts.planted
    np.testing.assert_allclose(over[planted], clip.straight[:, columns, 1][planted], atol=1e-9)
    assert foot_skate(clip.edited, clip.contacts, NAMES) < 1e-9
    assert foot_skate(clip.bent, clip.contacts, NAMES) > 0.05  # bending alone slides them


def test_a_height_field_is_bilinear_and_clamped(tmp_path):
    xs, zs = np.arange(6) * 50.0 - 100, np.arange(4) * 50.0
    heights = 0.1 * xs[None, :] + 0.2 * zs[:, None]
    np.savez(tmp_path / "ground.npz", heights=heights, cell_cm=50.0, origin_cm=[-100.0, 0.0])
    field = read_height_field(tmp_path / "ground.npz")
    assert isinstance(field, HeightField)
    np.testing.assert_allclose(
        field.height(np.array([-60.0, 33.0]), np.array([10.0, 120.0])), [-6 + 2, 3.3 + 24]
    )
    assert field.height(np.array(1000.0), np.array(0.0)) == pytest.approx(0.1 * 150)


def _one_line(error) -> str:
    message = str(error.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize(
    ("text", "suffix", "says"),
    [
        ("points: [[0, 0]]", ".yaml", "N>=2"),
        ("points: [[0, 0], [0, 0], [1, 1]]", ".yaml", "same"),
        ("points: [[0, .nan], [1, 1]]", ".yaml", "NaN"),
        ("points: [[0, a], [1, 1]]", ".yaml", "numbers"),
        ("[1, 2]", ".yaml", "mapping"),
        ('{"points": [[0, 0], [1, 1]], "unit": "ft"}', ".json", "unit"),
        ("{points: [[0, 0]", ".yaml", "unreadable"),
        ("points: [[0, 0], [1, 1]]", ".txt", ".yaml"),
    ],
)
def test_bad_path_files_are_refused_in_one_line(tmp_path, text, suffix, says):
    path = tmp_path / f"path{suffix}"
    path.write_text(text)
    with pytest.raises(PathOptionError) as error:
        path_edit_from_options({"path": str(path)})
    message = _one_line(error)
    assert message.startswith("map.path: ") and says in message and str(path) in message


def _npz(path, **arrays):
    np.savez(path, **arrays)
    return path


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (lambda d: _npz(d / "a.npz", cell_cm=10.0), "no 'heights'"),
        (lambda d: _npz(d / "b.npz", heights=np.zeros(5), cell_cm=10.0), "2-D"),
        (lambda d: _npz(d / "c.npz", heights=np.full((3, 3), np.inf), cell_cm=10.0), "NaN"),
        (lambda d: _npz(d / "d.npz", heights=np.zeros((3, 3)), cell_cm=-1.0), "cell size"),
        (lambda d: (np.save(d / "e.npy", np.zeros((3, 3))), d / "e.npy")[1], "cell size"),
        (lambda d: d / "missing.npz", "does not exist"),
        (lambda d: (d / "f.npz").write_text("not a zip") and d / "f.npz", "unreadable"),
    ],
)
def test_bad_terrain_files_are_refused_in_one_line(tmp_path, make, says):
    path = make(tmp_path)
    good = tmp_path / "path.json"
    good.write_text(json.dumps({"points": [[0, 0], [0, 100]]}))
    with pytest.raises(PathOptionError) as error:
        path_edit_from_options({"path": str(good), "terrain": str(path)})
    message = _one_line(error)
    assert message.startswith("map.terrain: ") and says in message


@pytest.mark.parametrize(
    ("options", "says"),
    [
        ({"terrain": "hills"}, "map.terrain='hills'"),
        ({"loop_seconds": -1.0}, "map.loop_seconds=-1.0"),
        ({"loop_seconds": "6"}, "map.loop_seconds='6'"),
        ({"terrain_shape": {"height": 1}}, "map.terrain_shape: unknown keys ['height']"),
        ({"terrain": "sine", "terrain_shape": {"wavelength_cm": 0}}, "map.terrain_shape"),
    ],
)
def test_bad_options_are_refused_in_one_line(tmp_path, options, says):
    good = tmp_path / "path.yaml"
    good.write_text("points: [[0, 0], [0, 100]]")
    with pytest.raises(PathOptionError) as error:
        path_edit_from_options({"path": str(good), **options})
    assert says in _one_line(error)
    with pytest.raises(PathOptionError, match=r"need map\.path"):
        path_edit_from_options({"loop_seconds": 6.0})
    assert path_edit_from_options({"terrain": "flat"}) is None


def test_a_clip_that_does_not_travel_is_refused():
    world = walker(60)
    world[:, :, [0, 2]] = world[:1, :, [0, 2]]
    with pytest.raises(PathEditError, match="travels"):
        edit(world, GroundPath(np.array([[0.0, 0.0], [0.0, 100.0]])))


def test_read_path_scales_metres(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("unit: m\npoints: [[0, 0], [0, 2.5]]")
    assert read_path(path).length_cm == pytest.approx(250.0)
    with pytest.raises(TerrainError):
        Procedural("hills")
