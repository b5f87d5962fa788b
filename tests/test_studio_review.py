"""The studio's Review view (issue #43, item 2) on a real ``rigmap map`` output folder.

A small biped project is built as ``tests/test_map_app.py`` builds it (the train corpus and
its poses, a small GPR) and twelve frames of the CMU walk are mapped into the served folder;
the view is checked on the server (joints, refusals, playback at the clip's fps) and in
Chromium (a mapped clip plays and scrubs; its screenshot is ``docs/studio/review.png``).
"""

from __future__ import annotations

import json
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rigmap.cli import compose_config, find_config_dir
from rigmap.rigs import load
from rigmap.studio.scene import to_scene
from rigmap.studio.served_folder import ServedFolder

ROOT = Path(__file__).resolve().parents[1]
WALK = ROOT.parent / "shared" / "mocap" / "cmu_131_01_walk.bvh"
CONF = find_config_dir(ROOT / "conf")
SMALL_MODEL = ["budget.gpr_points=80", "budget.length_scales=3", "budget.cv_splits=2"]
FRAMES = 12
CLIP = "maps/cmu_131_01_walk"  # where the map writes it, relative to the served folder
WAIT_MS = 30_000  # software WebGL on two shared cores: generous
#: viser keeps a point cloud's points as float16: 1 mm at 2 m (a walk moves ~4 cm a frame)
SENT = 2e-3
VIEWPORT = {"width": 1200, "height": 900}  # tall enough for the timeline in the screenshot


@pytest.fixture(scope="module")
def served(tmp_path_factory, biped) -> Path:
    """A served folder holding one map output (12 frames of the walk at 30 fps), a folder
    with another tool's summary.json, and the project beside it (not served)."""
    from omegaconf import OmegaConf

    from rigmap.animation.corpus_files import pose_corpora, write_corpora
    from rigmap.app.map_job import map_from_config
    from rigmap.app.stage import stage_config
    from rigmap.store import Layout

    root = tmp_path_factory.mktemp("review")
    layout = Layout(data=root / "project" / "data", models=root / "project" / "models")
    write_corpora(biped, layout, seed=0, fps=24, variation=1.0)
    pose_corpora(biped, layout, batch_size=512, progress=False)
    served = root / "served"
    overrides = [
        "rig=biped", f"paths.data={layout.data}", f"paths.models={layout.models}",
        *SMALL_MODEL, f"input={WALK}", f"out={served / 'maps'}", "map.first_frame=240",
        f"map.frames={FRAMES}", "map.settings.refine_iterations=1", "map.preview=false",
    ]  # fmt: skip
    config = OmegaConf.to_container(
        stage_config(compose_config(overrides, CONF, config_name="map")), resolve=True
    )
    (clip,) = map_from_config(config, config_dir=CONF, log=lambda _line: None)
    assert clip.folder.resolve() == (served / CLIP).resolve()
    other = served / "metrics"
    other.mkdir()
    (other / "summary.json").write_text(json.dumps({"format": "something else"}))
    return served


@pytest.fixture(scope="module")
def studio(served):
    """A Review view on a running server (no page open)."""
    from rigmap.studio.app import Studio
    from rigmap.studio.review_view import ReviewView

    view = ReviewView(ServedFolder(served), load)
    running = Studio([view], port=0)
    yield running, view
    running.stop()


def world_joints_of(rig, folder: Path) -> np.ndarray:
    """Every frame's joints from controls.parquet, as the map wrote it (frame-sorted)."""
    controls = pd.read_parquet(folder / "controls.parquet").sort_values("frame")
    pose = rig.pose(controls[list(rig.control_names)].to_numpy(dtype=np.float64))
    return np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]


def test_the_folder_menu_lists_map_outputs_only(studio):
    _, view = studio
    assert view.map_outputs() == [CLIP]
    assert list(view.menu.options) == ["(pick a map output)", CLIP]


def test_the_view_poses_the_rig_from_controls_and_the_source_from_targets(studio, served, biped):
    _, view = studio
    view.menu.value = CLIP  # as a pick in the page does
    clip = view.clip
    assert clip is not None and clip.name == CLIP, view.message.content
    folder = served / CLIP
    expected = world_joints_of(biped, folder)
    assert clip.rig_joints.shape == (FRAMES, biped.n_joints, 3)
    np.testing.assert_allclose(clip.rig_joints, expected, atol=1e-9)

    # the source is the map's targets: frames.parquet's error is measured against them
    summary = json.loads((folder / "summary.json").read_text())
    assert clip.source_names == tuple(summary["mapped_joints"])
    mapped = [biped.joint_names.index(j) for j in clip.source_names]
    error = np.sqrt(((expected[:, mapped] - clip.source_joints) ** 2).sum(axis=2).mean(axis=1))
    frames = pd.read_parquet(folder / "frames.parquet")
    np.testing.assert_allclose(error, frames["joint_error_cm"], rtol=1e-6, atol=1e-6)
    assert clip.fps == pytest.approx(30.0, rel=1e-4)

    # drawn side by side: the source shifted sideways past the rig, never overlapping it
    assert clip.offset_cm[0] > 0 and clip.offset_cm[1:].tolist() == [0.0, 0.0]
    gap = (clip.source_joints[..., 0] + clip.offset_cm[0]).min() - clip.rig_joints[..., 0].max()
    assert gap > 0.2 * biped.rest_height()

    # the scene shows the frame asked for; the keys and feet are read
    view.slider.value = 7
    np.testing.assert_allclose(view.rig_drawing.points.points, to_scene(expected[7]), atol=SENT)
    np.testing.assert_allclose(
        view.source_drawing.points.points,
        to_scene(clip.source_joints[7] + clip.offset_cm),
        atol=SENT,
    )
    keys = json.loads((folder / "keys.json").read_text())["curves"]
    assert int(clip.keys_per_frame.sum()) == sum(len(k) for k in keys.values())
    assert int(clip.keys_per_frame.sum()) == summary["keys"]
    planted = {c.removeprefix("planted."): frames[c] for c in frames if c.startswith("planted.")}
    assert planted and set(clip.planted) == set(planted)
    assert view.status.content.startswith(
        f"frame 7 / {FRAMES - 1} · joint error {frames['joint_error_cm'][7]:.2f} cm · "
        f"confidence {frames['confidence'][7]:.2f}"
    )
    foot = next(iter(planted))
    state = "planted" if planted[foot][7] else "lifted"
    assert f"{foot} {state}" in view.contacts_text.content


def test_a_planted_foots_slide_is_what_foot_skate_averages(studio, served, biped):
    """The per-frame slides of the planted feet average to summary.json's result skate."""
    _, view = studio
    clip = view.open(CLIP)
    slides = [
        clip.slide_cm(foot, frame)
        for foot in clip.planted
        for frame in range(clip.n_frames)
        if clip.slide_cm(foot, frame) is not None
    ]
    assert slides
    summary = json.loads((served / CLIP / "summary.json").read_text())
    assert np.mean(slides) == pytest.approx(summary["foot_skate_result_cm_per_frame"], rel=1e-3)


def test_an_output_without_targets_shows_the_rig_alone_and_says_why(studio, served):
    _, view = studio
    older = served / "older" / "walk"
    if not older.exists():
        shutil.copytree(served / CLIP, older)
        (older / "targets.parquet").unlink()
    clip = view.open("older/walk")
    assert clip is not None and clip.source_joints is None and view.source_drawing is None
    assert "No targets.parquet" in view.message.content
    np.testing.assert_allclose(clip.rig_joints, view.open(CLIP).rig_joints)
    assert view.source_drawing is not None


def _drop_column(folder: Path, file: str, column: str) -> None:
    table = pd.read_parquet(folder / file)
    table.drop(columns=[column]).to_parquet(folder / file, index=False)


def _other_rig(folder: Path) -> None:
    summary = json.loads((folder / "summary.json").read_text())
    (folder / "summary.json").write_text(json.dumps({**summary, "rig": "no_such_rig"}))


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda f: _drop_column(f, "controls.parquet", "root.tx"),
         "bad/controls.parquet: lacks 1 controls of rig 'biped' (first 'root.tx')"),
        (lambda f: pd.read_parquet(f / "frames.parquet")[:5].to_parquet(f / "frames.parquet"),
         "bad/frames.parquet: 5 frames, controls.parquet has 12"),
        (lambda f: _drop_column(f, "targets.parquet", "pelvis.x"),
         "bad/targets.parquet: lacks the columns of summary.json's mapped_joints (first "
         "'pelvis.x')"),
        (lambda f: (f / "controls.parquet").write_bytes(b"PAR1 cut short"),
         "bad/controls.parquet: unreadable"),
        (_other_rig, "bad/summary.json: rig 'no_such_rig':"),
    ],
)  # fmt: skip
def test_a_damaged_map_output_is_one_message_naming_its_file(studio, served, damage, message):
    _, view = studio
    bad = served / "bad"
    shutil.rmtree(bad, ignore_errors=True)
    shutil.copytree(served / CLIP, bad)
    try:
        damage(bad)
        assert view.open("bad") is None
        assert message in view.message.content
        assert "\n" not in view.message.content
    finally:
        shutil.rmtree(bad)


@pytest.mark.parametrize(
    ("typed", "message"),
    [
        ("../project", "'..' is refused"),
        ("ABSOLUTE", "absolute paths are refused"),
        ("escape", "leads outside"),
        ("metrics", "format 'something else', expected 'rigmap.map_summary/1'"),
        ("maps", "no summary.json; not a rigmap map output"),
        ("nowhere", "no such folder"),
    ],
)
def test_a_typed_folder_out_of_the_served_one_is_refused_in_the_page(
    studio, served, typed, message
):
    _, view = studio
    link = served / "escape"
    if not link.is_symlink():
        link.symlink_to(served.parent / "project", target_is_directory=True)
    if typed == "ABSOLUTE":
        typed = str(served / CLIP)  # even a map output inside, named absolutely
    assert view.open(CLIP) is not None
    view.typed.value = typed
    assert view.open(view.typed.value) is None
    assert message in view.message.content
    assert view.message.content.startswith("**Not opened:**")
    assert view.clip.name == CLIP  # the clip shown stays


def test_playback_runs_at_the_clips_fps_and_stops_at_the_end_without_loop(studio):
    _, view = studio
    clip = view.open(CLIP)
    view.loop.value = False
    try:
        started = time.monotonic()
        view.play()
        assert view.play_button.label == "Pause"
        deadline = started + 30
        while view.playing and time.monotonic() < deadline:
            time.sleep(0.01)
        elapsed = time.monotonic() - started
    finally:
        view.loop.value = True
        view.pause()
    assert view.frame == clip.n_frames - 1 and view.play_button.label == "Play"
    assert elapsed >= (clip.n_frames - 1) / clip.fps - 0.02  # not faster than the clip


# --------------------------------------------------------------------------- in Chromium
def _text_input(page, label: str):
    """viser's text box (its <label> names no input: found through the row)."""
    return page.locator(
        f"xpath=//label[text()='{label}']/ancestor::div[contains(@class,'mantine-Flex-root')][1]"
        "//input"
    )


def _shown_frame(status) -> int:
    return int(re.match(r"frame (\d+) /", status.inner_text()).group(1))


def _colour_pixels(png: bytes, colour, width: int) -> int:
    """Pixels within 40 of ``colour`` (RGB) in the ``width`` leftmost columns."""
    import io

    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int64)[:, :width]
    return int((np.abs(image - np.array(colour)).max(axis=2) < 40).sum())


@pytest.mark.browser
def test_a_mapped_clip_plays_and_scrubs_in_chromium(served):
    from browser import chromium_page, keep_screenshot
    from rigmap.studio.app import Studio
    from rigmap.studio.review_view import RIG_COLOR, SOURCE_COLOR, ReviewView

    view = ReviewView(ServedFolder(served), load)
    studio = Studio([view], port=0)
    try:
        with chromium_page(studio.url, viewport=VIEWPORT) as page:
            page.set_default_timeout(WAIT_MS)
            # a typed folder out of the served one: refused, the message in the page
            _text_input(page, "Folder").fill("../project")
            page.get_by_role("button", name="Open folder").click()
            page.get_by_text("'..' is refused").wait_for()
            assert view.clip is None

            page.get_by_label("Map output").click()
            page.get_by_role("option", name=CLIP).click()
            status = page.get_by_text(re.compile(rf"^frame \d+ / {FRAMES - 1} · joint error"))
            status.wait_for()
            assert _shown_frame(status) == 0 and view.clip.name == CLIP
            first = view.rig_drawing.points.points.copy()

            # Play: the page's frame counter advances, the server's skeleton moves (sampled
            # while it plays: the 12-frame clip loops, so one look may land on frame 0 again)
            page.get_by_role("button", name="Play").click()
            seen, moved = {_shown_frame(status)}, False
            deadline = time.monotonic() + WAIT_MS / 1000
            while (len(seen) < 4 or not moved) and time.monotonic() < deadline:
                page.wait_for_timeout(150)
                seen.add(_shown_frame(status))
                moved = moved or not np.allclose(view.rig_drawing.points.points, first)
            assert len(seen) >= 4, seen
            assert moved
            page.get_by_role("button", name="Pause").click()
            page.get_by_role("button", name="Play").wait_for()
            assert not view.playing

            # scrub with the keyboard: the last frame, then three back
            slider = page.get_by_role("slider")
            slider.focus()
            page.keyboard.press("End")
            page.get_by_text(f"frame {FRAMES - 1} / {FRAMES - 1} ·").wait_for()
            for _ in range(3):
                page.keyboard.press("ArrowLeft")
            page.get_by_text(f"frame {FRAMES - 4} / {FRAMES - 1} ·").wait_for()
            assert view.frame == FRAMES - 4
            np.testing.assert_allclose(
                view.rig_drawing.points.points,
                to_scene(view.clip.rig_joints[FRAMES - 4]),
                atol=SENT,
            )

            # scrub with the mouse: drag the thumb to about a third of the track
            track = page.locator(".mantine-Slider-track").bounding_box()
            thumb = slider.bounding_box()
            page.mouse.move(thumb["x"] + thumb["width"] / 2, thumb["y"] + thumb["height"] / 2)
            page.mouse.down()
            page.mouse.move(track["x"] + track["width"] / 3, track["y"] + track["height"] / 2)
            page.mouse.up()
            page.wait_for_function(
                f"() => document.querySelector('[role=slider]')"
                f".getAttribute('aria-valuenow') != '{FRAMES - 4}'"
            )
            dragged = int(slider.get_attribute("aria-valuenow"))
            assert abs(dragged - (FRAMES - 1) / 3) <= 1, dragged
            page.get_by_text(f"frame {dragged} / {FRAMES - 1} ·").wait_for()
            assert view.frame == dragged

            # both skeletons on the canvas (blue rig, black source), kept as the docs' picture
            close = page.locator(".mantine-Notification-closeButton")
            if close.count():
                close.first.click()
            page.wait_for_timeout(1500)
            png = page.screenshot()
            left = int(page.get_by_text("Connected").bounding_box()["x"]) - 40  # the panel's
            assert _colour_pixels(png, RIG_COLOR, left) > 200
            assert _colour_pixels(png, SOURCE_COLOR, left) > 200
            keep_screenshot(png, "review.png")
    finally:
        studio.stop()
