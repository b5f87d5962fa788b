"""`rigmap studio`'s Pose view (issue #43): served and written folders, the camera's
projection, the bind address, and in a real Chromium: a drag with mouse events on an
effector's gizmo poses the rig (the server's pose and the page's pixels both change)."""

from __future__ import annotations

import io
import json
import os
import socket
import time
from pathlib import Path

import numpy as np
import pytest

from rigmap.studio.camera import front_camera, screen_point
from rigmap.studio.served_folder import ServedFolder, StudioFileError
from rigmap.studio.writes import OutputFolder

CONF = Path(__file__).resolve().parents[1] / "conf"
SMALL_MODEL = ["budget.gpr_points=80", "budget.length_scales=3", "budget.cv_splits=2"]


# --------------------------------------------------------------------------- folders
def test_the_served_folder_refuses_paths_that_leave_it(tmp_path):
    root = tmp_path / "project"
    (root / "outputs" / "map").mkdir(parents=True)
    (root / "outputs" / "map" / "summary.json").write_text("{}")
    (tmp_path / "secret").mkdir()
    (root / "out_link").symlink_to(tmp_path / "secret")
    served = ServedFolder(root)
    assert served.resolve("outputs/map", kind="folder") == (root / "outputs/map").resolve()
    assert served.folders_with("summary.json") == ["outputs/map"]
    for path, message in (
        ("../secret", "'..' is refused"),
        ("outputs/../../secret", "'..' is refused"),
        (str(tmp_path / "secret"), "absolute paths are refused"),
        ("out_link", "leads outside"),
        ("outputs/nothing", "no such path"),
        ("", "no path given"),
    ):
        with pytest.raises(StudioFileError, match=message):
            served.resolve(path)
    with pytest.raises(StudioFileError, match="not a file"):
        served.resolve("outputs/map", kind="file")
    with pytest.raises(StudioFileError, match="not a folder"):
        ServedFolder(root / "outputs/map/summary.json")


def test_the_output_folder_writes_only_inside_it(tmp_path):
    out = OutputFolder(tmp_path / "out")
    path = out.write_json("pose/biped-1.json", {"a": np.float64(1.5)})
    assert json.loads(path.read_text()) == {"a": 1.5} and out.relative(path) == "pose/biped-1.json"
    for name in ("../x.json", "/tmp/x.json", "a/../../x.json"):
        with pytest.raises(StudioFileError, match="not a name inside"):
            out.write_json(name, {})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_the_camera_puts_what_it_frames_on_the_canvas():
    points = np.array([[-0.9, 0.0, -0.2], [0.9, 1.8, 0.2]])
    camera = front_camera(points)
    x, y = screen_point(camera, camera.look_at, 1000, 700)
    assert (x, y) == pytest.approx((500, 350))
    for point in points:
        px, py = screen_point(camera, point, 1000, 700)
        assert 0 < px < 1000 and 0 < py < 700
    left, _ = screen_point(camera, [-0.5, 0.9, 0], 1000, 700)
    right, _ = screen_point(camera, [0.5, 0.9, 0], 1000, 700)
    top = screen_point(camera, [0, 1.5, 0], 1000, 700)[1]
    assert left < right and top < 350  # +X is right, +Y is up on the page
    with pytest.raises(ValueError, match="behind the camera"):
        screen_point(camera, camera.position + np.array([0, 0, 1.0]), 1000, 700)


# --------------------------------------------------------------------------- the server
@pytest.fixture(scope="module")
def project(tmp_path_factory, biped):
    """data/<rig>/corpus and poses of a temporary project for the biped and the face."""
    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.rigs import load
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("project")
    layout = Layout(data=root / "data", models=root / "models")
    for rig in (biped, load("face")):
        write_corpora(rig, layout, seed=0, fps=24, variation=1.0)
        pose_corpora(rig, layout, batch_size=512, progress=False)
    return root


@pytest.fixture(scope="module")
def studio(project):
    from rigmap.app.studio import build_studio

    overrides = [f"paths.data={project / 'data'}", f"paths.models={project / 'models'}"]
    served = build_studio(
        rigs=["biped", "face"],
        overrides=[*overrides, *SMALL_MODEL],
        config_dir=CONF,
        folder=project,
        out=project / "studio_out",
        host="127.0.0.1",
        port=0,
    )
    yield served
    served.stop()


def test_it_binds_the_loopback_address_only(studio):
    import psutil

    listening = [
        c.laddr.ip
        for c in psutil.net_connections(kind="tcp")
        if c.status == psutil.CONN_LISTEN and c.laddr.port == studio.port
    ]
    assert listening and set(listening) <= {"127.0.0.1"}
    assert studio.url == f"http://127.0.0.1:{studio.port}"
    with socket.create_connection(("127.0.0.1", studio.port), timeout=5):
        pass


def _canvas_pixels(page) -> np.ndarray:
    from PIL import Image

    png = page.locator("canvas").first.screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


@pytest.mark.browser
@pytest.mark.parametrize(("rig", "joint"), [("biped", "hand_r"), ("face", None)])
def test_dragging_an_effector_with_the_mouse_poses_the_rig(studio, rig, joint):
    from browser import chromium_page, keep_screenshot
    from rigmap.studio import probe

    view = studio.views["Pose"]
    view.rig_menu.value = rig  # as picking it in the page does
    joint = joint or view.session.effectors[0]
    rest = view.record.controls.copy()
    count = view.record.count
    with chromium_page(studio.url) as page:
        box = probe.canvas_box(page)
        probe.watch_poses(page)
        time.sleep(1.0)  # the first frame drawn
        before = _canvas_pixels(page)
        gizmo_before = np.array(view.gizmo(joint).position)
        start = probe.gizmo_point(view, joint, box)
        latencies = probe.timed_drag(page, start, probe.wiggle(start, 6, step_px=4.0, span=6))
        time.sleep(0.5)
        after = _canvas_pixels(page)
        keep_screenshot(page.screenshot(), f"pose_{rig}.png")
    moved = np.array(view.gizmo(joint).position) - gizmo_before
    assert moved[0] > 0.001 and abs(moved[1]) < 1e-9 and abs(moved[2]) < 1e-9  # along +X only
    assert view.record.count >= count + len(latencies) and len(latencies) == 6
    used = view.session.rig.controls.used_indices
    assert np.abs(view.record.controls[used] - rest[used]).max() > 1e-3  # the rig moved
    assert view.record.distance_cm < 2.0  # and it reached the dragged effector
    changed = np.abs(after - before).sum(axis=2) > 30
    assert changed.mean() > 1e-3  # the page shows it


@pytest.mark.browser
def test_the_page_exports_the_pose_into_the_output_folder_only(studio, project):
    from browser import chromium_page

    view = studio.views["Pose"]
    view.rig_menu.value = "biped"
    before = set(os.listdir(project))
    with chromium_page(studio.url) as page:
        page.get_by_role("button", name="Export pose (JSON)").click()
        page.wait_for_function(
            "() => document.body.textContent.includes('Exported pose/biped-')", timeout=60_000
        )
    (written,) = (project / "studio_out" / "pose").glob("biped-*.json")
    document = json.loads(written.read_text())
    rig = view.session.rig
    assert document["rig"] == "biped" and set(document["effectors"]) == set(view.session.effectors)
    assert sorted(document["used_controls"]) == sorted(rig.used_controls)
    assert set(os.listdir(project)) - before <= {"studio_out"}


def test_the_command_line_names_a_bad_folder(tmp_path, capsys):
    from rigmap.cli import main

    assert main(["studio", "--folder", str(tmp_path / "none"), "--port", "0"]) != 0
    assert "--folder" in capsys.readouterr().err
