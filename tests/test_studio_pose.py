"""`rigmap studio`'s Pose page (issue #43): served and written folders, the camera's
projection, the bind address, what the pages serve and refuse, and in a real Chromium: a
drag with mouse events on an effector's handle poses the rig (the server's pose and the
page's pixels both change)."""

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
        pages_port=0,
    )
    yield served
    served.stop()


def test_it_binds_the_loopback_address_only(studio):
    import psutil

    for port in (studio.port, studio.pages.port):
        listening = [
            c.laddr.ip
            for c in psutil.net_connections(kind="tcp")
            if c.status == psutil.CONN_LISTEN and c.laddr.port == port
        ]
        assert listening and set(listening) <= {"127.0.0.1"}
        with socket.create_connection(("127.0.0.1", port), timeout=5):
            pass
    assert studio.url == f"http://127.0.0.1:{studio.port}"
    assert studio.pages.links() == {"Pose": f"http://127.0.0.1:{studio.pages.port}/"}


# --------------------------------------------------------------------------- the Pose page
def _get(port: int, path: str) -> tuple[int, str, dict]:
    """A raw GET of ``path`` as sent (no client-side normalising of ``..``)."""
    import http.client

    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    try:
        connection.request("GET", path)
        response = connection.getresponse()
        return response.status, response.read().decode(), dict(response.getheaders())
    finally:
        connection.close()


def test_the_pages_serve_their_own_files_and_nothing_else(studio):
    port = studio.pages.port
    status, body, headers = _get(port, "/")
    assert status == 200 and "rigmap studio · Pose" in body
    assert headers["Content-Security-Policy"].startswith("default-src 'self'")
    assert _get(port, "/pose.js")[0] == 200 and _get(port, "/studio.css")[0] == 200
    for path in ("/../pyproject.toml", "/%2e%2e/pyproject.toml", "/etc/passwd", "/page/pose.js"):
        status, body, _ = _get(port, path)
        assert status == 404 and "not served" in body, path
    status, body, _ = _get(port, "/play")  # no latent models in this project: no Play page
    assert status == 404 and "not served" in body


def test_the_pose_socket_refuses_other_origins_and_bad_commands(studio):
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    from rigmap.studio.page_server import decode

    url = f"ws://127.0.0.1:{studio.pages.port}/pose/ws"
    with pytest.raises(InvalidStatus, match="403"):
        connect(url, origin="http://attacker.example").close()
    with pytest.raises(InvalidStatus, match="404"):
        connect(f"ws://127.0.0.1:{studio.pages.port}/nothing/ws").close()
    driver = studio.pages["pose"].driver
    before = driver.targets.copy()
    with connect(url, origin=f"http://127.0.0.1:{studio.pages.port}") as socket_:
        greeting = [decode(socket_.recv(timeout=10))[0]["type"] for _ in range(3)]
        assert greeting == ["rigs", "scene", "links"]
        effector = driver.session.effectors[0]
        for command, message in (
            ("{not json", "not JSON"),
            ('["drag"]', "a JSON object with a type"),
            ('{"type": "shell", "cmd": "touch /tmp/x"}', "unknown command 'shell'"),
            ('{"type": "rig", "name": "../../etc"}', "rig '../../etc': not one of"),
            ('{"type": "drag", "phase": "fly", "target": [0, 0, 0]}', "drag phase 'fly'"),
            (
                f'{{"type": "drag", "phase": "move", "effector": "{effector}", "target": [0, 0]}}',
                "expected [x, y, z]",
            ),
            (
                f'{{"type": "drag", "phase": "move", "effector": "{effector}", '
                '"target": [NaN, 0, 0]}',
                "three finite numbers",
            ),
            (
                '{"type": "drag", "phase": "move", "effector": "tail", "target": [0, 0, 0]}',
                "'tail': not an effector",
            ),
        ):
            socket_.send(command)
            header, _ = decode(socket_.recv(timeout=10))
            assert header["type"] == "error" and message in header["message"], command
    np.testing.assert_array_equal(driver.targets, before)  # nothing was acted on


def _canvas_pixels(page) -> np.ndarray:
    from PIL import Image

    png = page.locator("canvas").first.screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def _pick_rig(page, rig: str, driver) -> None:
    """The rig chosen in the page's menu, as a user does, and its scene drawn; a page that
    never shows it fails with what the page and the server said."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.wait_for_selector("#rig option", state="attached", timeout=60_000)
    page.select_option("#rig", rig)
    try:
        page.wait_for_function(
            "(r) => document.getElementById('status').textContent.startsWith(r + ' ·')",
            arg=rig,
            polling=100,  # a timer, not animation frames: the check runs however the page draws
            timeout=180_000,  # the first load fits the rig's effector mapping
        )
    except PlaywrightTimeout:
        shown = page.evaluate(
            "() => [document.getElementById('status').textContent,"
            " document.getElementById('error').textContent]"
        )
        pytest.fail(
            f"{rig} not shown: page {shown}, page errors {errors}, server {driver.status!r}",
            pytrace=False,
        )


@pytest.mark.browser
@pytest.mark.parametrize(("rig", "joint"), [("biped", "hand_r"), ("face", None)])
def test_dragging_an_effector_with_the_mouse_poses_the_rig(studio, rig, joint):
    from browser import chromium_page, keep_screenshot
    from rigmap.studio import probe

    pose = studio.pages["pose"]
    driver = pose.driver
    with chromium_page(studio.pages.url) as page:
        _pick_rig(page, rig, driver)
        joint = joint or driver.session.effectors[0]
        k = driver.session.effectors.index(joint)
        rest, count = driver.record.controls.copy(), driver.record.count
        target_before = driver.targets[k].copy()
        box = probe.canvas_box(page)
        probe.watch_poses(page)
        time.sleep(1.0)  # the first frame drawn
        before = _canvas_pixels(page)
        start = probe.handle_point(pose, joint, box)
        latencies = probe.timed_drag(page, start, probe.wiggle(start, 6, step_px=4.0, span=6))
        time.sleep(0.5)
        after = _canvas_pixels(page)
        keep_screenshot(page.screenshot(), f"pose_{rig}.png")
    moved = driver.targets[k] - target_before
    # the handle moves in the camera's view plane: a move to the right is +X only
    assert moved[0] > 0.1 and abs(moved[1]) < 1e-9 and abs(moved[2]) < 1e-9
    assert driver.record.count >= count + len(latencies) and len(latencies) == 6
    used = driver.session.rig.controls.used_indices
    assert np.abs(driver.record.controls[used] - rest[used]).max() > 1e-3  # the rig moved
    assert driver.record.distance_cm < 2.0  # and it reached the dragged effector
    changed = np.abs(after - before).sum(axis=2) > 30
    assert changed.mean() > 1e-3  # the page shows it


@pytest.mark.browser
def test_the_page_exports_the_pose_into_the_output_folder_only(studio, project):
    from browser import chromium_page

    driver = studio.pages["pose"].driver
    before = set(os.listdir(project))
    with chromium_page(studio.pages.url) as page:
        _pick_rig(page, "biped", driver)
        page.get_by_role("button", name="Export pose (JSON)").click()
        page.wait_for_function(
            "() => document.body.textContent.includes('Exported pose/biped-')", timeout=60_000
        )
    (written,) = (project / "studio_out" / "pose").glob("biped-*.json")
    document = json.loads(written.read_text())
    rig = driver.session.rig
    assert document["rig"] == "biped" and set(document["effectors"]) == set(
        driver.session.effectors
    )
    assert sorted(document["used_controls"]) == sorted(rig.used_controls)
    assert set(os.listdir(project)) - before <= {"studio_out"}


def test_the_command_line_names_a_bad_folder_and_a_taken_port(tmp_path, capsys, project):
    from rigmap.cli import main

    assert main(["studio", "--folder", str(tmp_path / "none"), "--port", "0"]) != 0
    assert "--folder" in capsys.readouterr().err
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        data = [f"paths.data={project / 'data'}", f"paths.models={project / 'models'}"]
        arguments = ["--port", "0", "--pages-port", str(port), "--rigs", "face", *SMALL_MODEL]
        assert main(["studio", "--folder", str(project), *arguments, *data]) != 0
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert f"--pages-port {port}: cannot serve on 127.0.0.1" in error


@pytest.mark.browser
@pytest.mark.blender
def test_the_page_exports_the_faces_pose_as_a_blend_key_and_says_why_not_for_the_biped(
    studio, project
):
    """The face's pose as shape keys keyed at frame 1, read back from Blender: each key's
    weight is its control's (value - default) / (upper - default) (export_shape_key_blend);
    the biped, a rig with no Blender file and no mesh, is refused in the page."""
    from browser import chromium_page
    from rigmap.rigs.blender.shape_keys import read_shape_key_blend

    driver = studio.pages["pose"].driver
    with chromium_page(studio.pages.url) as page:
        _pick_rig(page, "biped", driver)
        page.get_by_role("button", name="Export .blend key").click()
        page.wait_for_function(
            "() => document.getElementById('error').textContent.includes('neither a Blender')",
            timeout=60_000,
        )
        _pick_rig(page, "face", driver)
        count = driver.record.count
        effector = driver.session.effectors[0]
        driver.drag(effector, driver.targets[0] + np.array([0.0, 0.4, 0.2]), phase="start")
        wait = time.monotonic() + 30
        while driver.record.count == count and time.monotonic() < wait:
            time.sleep(0.05)
        controls = driver.record.controls.copy()
        page.get_by_role("button", name="Export .blend key").click()
        page.wait_for_function(
            "() => document.body.textContent.includes('Exported pose/face-')", timeout=180_000
        )
    (written,) = (project / "studio_out" / "pose").glob("face-*.blend")
    rig = driver.session.rig
    used = rig.controls.used_indices
    table = read_shape_key_blend(written)
    row = table[table["frame"] == 1].iloc[0]
    lower, upper = rig.controls.defaults[used], rig.controls.upper[used]
    expected = (controls[used] - lower) / (upper - lower)
    got = np.array([row[name] for name in rig.used_controls])
    assert np.abs(expected).max() > 1e-3  # the drag moved the face
    np.testing.assert_allclose(got, expected, atol=1e-5)
    assert not list((project / "studio_out" / "pose").glob("biped-*.blend"))


def test_a_page_that_stops_reading_gets_only_the_newest_poses_and_every_other_message():
    """A page's outbox never grows without bound nor blocks the sender: past MAX_PENDING
    the oldest replaceable message (a pose) goes, the others (a scene, an error) stay."""
    import threading as threading_

    from rigmap.studio.page_server import MAX_PENDING, Outbox

    class Stalled:  # a connection whose page does not read until it is let go
        def __init__(self):
            self.sent, self.go = [], threading_.Event()

        def send(self, message):
            self.go.wait(10)
            self.sent.append(message)

    connection = Stalled()
    outbox = Outbox(connection, "pose")
    outbox.put(b"first")  # taken by the sender at once, which then waits in send
    time.sleep(0.2)
    for k in range(10):
        outbox.put(f"pose {k}".encode(), replaceable=True)
    outbox.put(b"scene")
    connection.go.set()
    deadline = time.monotonic() + 10
    while len(connection.sent) < MAX_PENDING + 1 and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.2)
    outbox.close()
    assert connection.sent[0] == b"first" and connection.sent[-1] == b"scene"
    kept = connection.sent[1:-1]
    assert kept == [f"pose {k}".encode() for k in range(10 - len(kept), 10)]
    assert len(connection.sent) <= MAX_PENDING + 1


def test_stopping_the_pages_closes_an_open_page_and_leaves_no_thread(project):
    """A page still open when the studio stops (Ctrl-C with a tab open) is disconnected,
    and the server's connection thread ends: nothing keeps the process alive."""
    import threading as threading_

    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    from rigmap.studio.page_server import Channel, PageServer

    pages = PageServer({"pose": Channel()}, host="127.0.0.1", port=0)
    before = set(threading_.enumerate())
    socket_ = connect(f"ws://127.0.0.1:{pages.port}/pose/ws")
    socket_.recv(timeout=10)  # the links message: the connection is served
    pages.stop()
    with pytest.raises(ConnectionClosed):
        while True:
            socket_.recv(timeout=10)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        started = [t for t in set(threading_.enumerate()) - before if not t.daemon]
        if not started:
            break
        time.sleep(0.05)
    assert not started, started
