"""The studio's Edit view (issue #43, item 3) on real CMU takes (subject 07's walks).

A served folder holds copies of two takes. The view opens 60 frames of one, its right hand
is dragged up and forward with the feet pinned, the edit is learned, applied to the other
take and a fix handed in. On the server: the drag is held by the IK over the frames (the
pinned feet stay, the hand goes its way), the view's files are what the library's own
calls (``rigmap edits learn``, ``apply --model``, ``fix``) make of the same inputs, typed
paths out of the served folder are refused in the page, and nothing is written outside the
output folder. In Chromium: the hand's gizmo dragged with the mouse, "Learn edit", another
clip picked, "Apply": the propagated hand is higher than its source's, and the page says
by how much.
"""

from __future__ import annotations

import json
import re
import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from rigmap.animation import read_bvh
from rigmap.app.edits import load_settings
from rigmap.edits.artist import apply_folder, learn_folder, read_track
from rigmap.edits.fixes import fix_folder
from rigmap.edits.skeleton_mode import skeleton_positions
from rigmap.studio.app import Studio
from rigmap.studio.edit_clips import hold_edit
from rigmap.studio.edit_view import FIX_HALF, PICK, SEGMENT, SUGGEST, EditView
from rigmap.studio.served_folder import ServedFolder
from rigmap.studio.writes import OutputFolder

ROOT = Path(__file__).resolve().parents[1]
MOCAP = ROOT.parent / "shared" / "mocap"
SOURCE, TARGET = "cmu_07_05.bvh", "cmu_07_06.bvh"
FRAMES, START, STOP = "100:160", 100, 160  # half a second at 120 fps: a quick fit
DRAG = (0.0, 3.0, 1.0)  # heading frame, file units: about 17 cm up and 6 cm forward
WAIT_MS = 30_000  # software WebGL on two shared cores: generous
NUMBER = r"([-+]\d+\.\d+)"
MOVED = re.compile(rf"RightHand moved \({NUMBER}, {NUMBER}, {NUMBER}\)")


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """``served/`` (copies of two takes, a text file, a symlink to a take outside it) and
    the output folder ``out/``, side by side in one temporary folder."""
    root = tmp_path_factory.mktemp("edit")
    served = root / "served"
    served.mkdir()
    for name in (SOURCE, TARGET):
        assert (MOCAP / name).is_file(), f"{MOCAP / name} is missing: the takes ship there"
        shutil.copy(MOCAP / name, served / name)
    (served / "notes.txt").write_text("not a clip\n")
    shutil.copy(MOCAP / "cmu_07_01.bvh", root / "outside.bvh")
    (served / "escape.bvh").symlink_to(root / "outside.bvh")
    return root, served, root / "out"


@pytest.fixture(scope="module")
def view(folders):
    """An Edit view on a running server (no page open)."""
    _, served, out = folders
    edit = EditView(ServedFolder(served), OutputFolder(out), load_settings())
    running = Studio([edit], port=0)
    yield edit
    running.stop()


@pytest.fixture(scope="module")
def learned(view):
    """The right hand dragged on 60 frames of the source, learned, applied to the target."""
    assert view.open(SOURCE, FRAMES) is not None, view.message.content
    view.drag("hand_r", DRAG)
    edit = view.learn()
    return edit, view.apply(TARGET)


def tree(root: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``root`` (relative) with its size and modification time."""
    return {
        p.relative_to(root).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in root.rglob("*")
        if p.is_file()
    }


def hand_lift(motion, frames) -> np.ndarray:
    """The right hand's height above the hips on ``frames`` (file units; Y is up)."""
    p = motion.global_positions()[frames]
    return p[:, motion.joint_index("RightHand"), 1] - p[:, motion.joint_index("Hips"), 1]


def test_the_clip_menu_lists_the_served_bvh_files_only(view):
    assert list(view.clip_menu.options) == [PICK, SOURCE, TARGET]  # not escape.bvh (leads out)
    assert list(view.apply_menu.options) == [PICK, SOURCE, TARGET]


def test_the_drag_is_held_by_the_ik_over_the_frames_with_the_feet_pinned(learned, folders):
    _, served, _ = folders
    edit, _ = learned
    source, edited = read_bvh(served / SOURCE), read_bvh(edit.edited)
    assert edited.n_frames == source.n_frames and edited.joint_names == source.joint_names
    outside = np.r_[0:START, STOP : source.n_frames]
    np.testing.assert_array_equal(edited.values[outside], source.values[outside])
    # the feet are pinned on every frame the IK solved (the others are interpolated)
    assert len(edit.failed) < 0.2 * (STOP - START), edit.failed
    solved = [f for f in range(START, STOP) if f - edit.source.clip.start not in edit.failed]
    p, q = source.global_positions(), edited.global_positions()
    for foot in ("LeftFoot", "RightFoot"):
        j = source.joint_index(foot)
        assert np.abs(q[solved, j] - p[solved, j]).max() < 1e-4  # the file's 6 decimals
    frames = np.arange(START, STOP)
    lift = hand_lift(edited, frames) - hand_lift(source, frames)
    assert lift.min() > 0 and lift.mean() > 0.6 * DRAG[1], (lift.min(), lift.mean())
    left = source.joint_index("LeftHand")
    assert np.abs((q[frames, left] - q[frames, 0]) - (p[frames, left] - p[frames, 0])).max() < 0.1


def test_ticked_joints_are_pinned_by_the_ik(learned, view):
    """The head dragged 3 units (17 cm) forward: with the feet ticked (the default) they
    stay to the IK's tolerance; unticked, the body's share of the pull moves them."""
    opened = learned[0].source
    frames = list(range(0, opened.n_frames, 15))
    feet = [opened.joint(name) for name in ("LeftFoot", "RightFoot")]
    before = skeleton_positions(opened.clip.track, opened.skeleton)[frames][:, feet]

    def feet_moved(pins) -> float:
        drag = {"Head": np.array([0.0, 0.0, 3.0])}
        track, failed = hold_edit(opened.clip.track, opened.skeleton, frames, drag, pins)
        assert not failed
        after = skeleton_positions(track, opened.skeleton)[frames][:, feet]
        return float(np.abs(after - before).max())

    assert set(view.pins(opened)) == {"LeftFoot", "RightFoot"}
    assert feet_moved(view.pins(opened)) < 1e-5
    try:
        for role in ("foot_l", "foot_r"):
            view.pin_boxes[role].value = False  # as unticking them in the page does
        assert view.pins(opened) == ()
        assert feet_moved(view.pins(opened)) > 1e-3
    finally:
        for role in ("foot_l", "foot_r"):
            view.pin_boxes[role].value = True


def test_the_page_shows_the_iks_pose_at_the_frame_shown(learned, view):
    """The blue skeleton is the IK's answer to the drag at the frame shown (the grey one the
    clip), on any frame of the range; the gizmo stays where the drag put it."""
    edit, _ = learned
    opened = edit.source
    hand = opened.joint("RightHand")
    for frame in (0, 37):
        view.frame_slider.value = opened.clip.start + frame  # as scrubbing does
        shown, ghost = (view.drawings[k].points.points[hand] for k in ("edit", "source"))
        lift = (shown[1] - ghost[1]) / opened.scale
        assert lift > 0.6 * DRAG[1], (frame, lift)
        gizmo = np.asarray(view.gizmo("hand_r").position)
        np.testing.assert_allclose(gizmo - ghost, np.asarray(DRAG) * opened.scale, atol=2e-3)


def test_learning_and_applying_in_the_view_are_the_librarys_own_calls(learned, folders, tmp_path):
    """The library on the same pair (the source and the view's edited file): the same
    learned.json, model and propagated clip, to the bit."""
    _, served, _ = folders
    edit, applied = learned
    library = tmp_path / "library"
    pair = (served / SOURCE, edit.edited, (START, STOP))
    learn_folder([pair], library / "model", load_settings())
    apply_folder(library / "model", served / TARGET, library / "applied")
    theirs = json.loads((library / "model" / "learned.json").read_text())
    for key in ("pairs", "joints", "fps", "kinematic_length_scale", "acceleration_length_scale"):
        assert edit.summary[key] == theirs[key], key
    assert edit.summary["pairs"][0]["frames"] == [START, STOP]
    assert edit.summary["pairs"][0]["example_frames"] == STOP - START
    np.testing.assert_array_equal(
        applied.track.values, read_track(library / "applied" / "cmu_07_06.npz").values
    )
    assert applied.bvh.read_text() == (library / "applied" / TARGET).read_text()


def test_the_status_says_what_was_learned_and_how_far_the_hand_moved(learned, folders, view):
    _, served, _ = folders
    _, applied = learned
    assert view.status.content.startswith(
        f"**Learned** {SOURCE} frames {START}:{STOP} → `edits/{Path(SOURCE).stem}_"
    )
    assert f"{STOP - START} example frames" in view.status.content
    # the reported move, checked from the files: the hand's height above the hips (Y is
    # up, so the heading frame's y is the world's), the target's T-pose frame 0 cut
    result, target = read_bvh(applied.bvh), read_bvh(served / TARGET)
    frames = np.arange(result.n_frames)
    up = float(np.mean(hand_lift(result, frames) - hand_lift(target, frames + 1)))
    moved = [float(v) for v in MOVED.search(view.result_status.content).groups()]
    assert moved[1] == pytest.approx(up, abs=0.006)
    assert up > 0.6 * DRAG[1] and moved[2] > 0.3 * DRAG[2]  # up and forward, as dragged


@pytest.mark.parametrize(
    ("typed", "message"),
    [
        ("../outside.bvh", "'..' is refused"),
        ("ABSOLUTE", "absolute paths are refused"),
        ("escape.bvh", "leads outside"),
        ("nothing.bvh", "no such file"),
        ("notes.txt", "'notes.txt': not a .bvh file"),
    ],
)
def test_a_typed_path_out_of_the_served_folder_is_refused_in_the_page(
    learned, folders, view, typed, message
):
    root, _, _ = folders
    edit, applied = learned
    if typed == "ABSOLUTE":
        typed = str(root / "outside.bvh")
    assert view.open(typed, FRAMES) is None
    assert view.message.content.startswith("**Not opened:**") and message in view.message.content
    assert view.source is edit.source and view.learned is edit  # what was open stays
    view.apply_text.value = typed
    view.apply_button.value = True  # as a click in the page does: the worker runs it
    assert view.wait_idle(60)
    assert view.message.content.startswith("**Applying the edit: not done.**")
    assert message in view.message.content and "\n" not in view.message.content
    assert view.result is applied


def test_bad_frames_are_one_line_naming_them(learned, view):
    for frames, message in (
        ("100-160", "Frames '100-160': expected START:STOP"),
        ("100:9999", "--frames 100:9999 is not a range within its 518 frames"),
    ):
        assert view.open(SOURCE, frames) is None
        assert message in view.message.content and "\n" not in view.message.content


def test_the_propagated_clip_plays_at_its_frame_rate(learned, view):
    _, applied = learned
    view.show_result_frame(0)
    started = time.monotonic()
    view.play()
    try:
        assert view.play_button.label == "Pause"
        time.sleep(0.5)
    finally:
        view.pause()
    elapsed = time.monotonic() - started
    expected = elapsed * applied.track.fps
    assert 0.5 * expected < view.result_frame <= expected + 1, (view.result_frame, expected)
    assert view.play_button.label == "Play"


def test_one_job_at_a_time_with_the_buttons_disabled_meanwhile(learned, view):
    release = threading.Event()
    assert view.submit("Waiting", lambda _progress: release.wait(30))
    try:
        assert view.learn_button.disabled and view.apply_button.disabled
        assert view.open_button.disabled and view.fix_button.disabled
        assert not view.submit("Another", lambda _progress: None)
        assert "**Busy:**" in view.message.content
        assert view.open(SOURCE, FRAMES) is None and view.source is learned[0].source
    finally:
        release.set()
    assert view.wait_idle(30)
    assert not view.learn_button.disabled and not view.apply_button.disabled
    assert view.message.content.startswith("Waiting: done in")


def test_a_fix_is_refitted_and_applied_again_writing_only_into_the_output_folder(
    view, folders, tmp_path
):
    root, served, _ = folders
    before = tree(root)
    assert view.open(SOURCE, FRAMES) is not None
    view.drag("hand_r", DRAG)
    edit = view.learn()
    view.apply(TARGET)
    copy = tmp_path / "model"  # the model before the fix, for the library's own refit
    shutil.copytree(edit.model, copy)
    view.result_slider.value = 201  # the target's file frame 201, as scrubbing does
    view.drag("hand_l", (0.0, 2.0, 0.0), on="result")
    report = view.hand_in_fix()
    assert report.frames == (201 - FIX_HALF, 201 + FIX_HALF + 1)
    assert report.after < 0.25 * report.before
    (fix,) = json.loads((edit.model / "learned.json").read_text())["fixes"]
    assert fix["frames"] == list(report.frames) and (edit.model / fix["file"]).is_file()
    assert f"{report.before:.3f} → {report.after:.3f}" in view.result_status.content
    # the library's fix on the copy, then its apply: the view's refitted clip, to the bit
    fix_folder(copy, served / TARGET, report.file, report.frames, load_settings(), SUGGEST, SEGMENT)
    apply_folder(copy, served / TARGET, tmp_path / "applied")
    np.testing.assert_array_equal(
        view.result.track.values, read_track(tmp_path / "applied" / "cmu_07_06.npz").values
    )
    after = tree(root)
    changed = sorted(k for k in after if before.get(k) != after[k])
    gone = sorted(set(before) - set(after))
    assert changed and not gone
    assert all(k.startswith("out/") for k in changed), changed


# --------------------------------------------------------------------------- in Chromium
def _text_input(page, label: str):
    """viser's text box (its <label> names no input: found through the row)."""
    return page.locator(
        f"xpath=//label[text()='{label}']/ancestor::div[contains(@class,'mantine-Flex-root')][1]"
        "//input"
    )


def _until(condition, what: str, timeout_s: float = WAIT_MS / 1000) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def _pick(page, view, menu: str, option: str, text) -> None:
    page.get_by_label(menu, exact=True).click()
    page.get_by_role("option", name=option).click()
    _until(lambda: text.value == option, f"{menu} = {option}")


def _mouse_drag(page, start, dy: float, steps: int = 10) -> None:
    """Press at ``start``, move ``dy`` pixels down (up when negative), release; paced as a
    hand does, above viser's 50 ms between a gizmo's updates."""
    from rigmap.studio.probe import PACE_S

    page.mouse.move(*start)
    page.mouse.down()
    for k in range(1, steps + 1):
        page.wait_for_timeout(1000 * PACE_S)
        page.mouse.move(start[0], start[1] + dy * k / steps)
    page.mouse.up()


@pytest.mark.browser
def test_an_edit_is_learned_and_applied_from_the_page(folders, tmp_path):
    from browser import chromium_page, keep_screenshot
    from rigmap.studio import probe

    _, served, _ = folders
    view = EditView(ServedFolder(served), OutputFolder(tmp_path / "out"), load_settings())
    studio = Studio([view], port=0)
    try:
        with chromium_page(studio.url) as page:
            page.set_default_timeout(WAIT_MS)
            box = probe.canvas_box(page)
            _text_input(page, "Frames").fill(FRAMES)
            _until(lambda: view.frames_text.value == FRAMES, "the typed frames")
            _pick(page, view, "Source clip", SOURCE, view.clip_text)
            page.get_by_text(f"{STOP - START} at 120 fps").wait_for()
            page.wait_for_timeout(1500)  # the camera's move drawn
            start = probe.gizmo_point(view, "hand_r", box, along=(0.0, 1.0, 0.0))
            _mouse_drag(page, start, -60.0)
            _until(lambda: "RightHand" in view.drags, "the drag on the server")
            page.wait_for_timeout(500)  # the drag's last update
            drag = view.drags["RightHand"]
            assert drag[1] > 1.0 and np.abs(drag[[0, 2]]).max() < 1e-6, drag  # along +Y only

            page.get_by_role("button", name="Learn edit").click()
            page.wait_for_function(
                "() => document.body.textContent.includes('example frames')", timeout=WAIT_MS
            )
            _pick(page, view, "Apply to", TARGET, view.apply_text)
            page.get_by_role("button", name="Apply", exact=True).click()
            page.wait_for_function(
                "() => document.body.textContent.includes('RightHand moved (')", timeout=WAIT_MS
            )
            shown = MOVED.search(page.locator("body").inner_text())
            close = page.locator(".mantine-Notification-closeButton")
            if close.count():
                close.first.click()
            page.wait_for_timeout(1000)
            keep_screenshot(page.screenshot(), "edit.png")
    finally:
        studio.stop()
    # the propagated clip's hand is higher than its source's, as the page reports
    result, target = read_bvh(view.result.bvh), read_bvh(served / TARGET)
    frames = np.arange(result.n_frames)
    up = float(np.mean(hand_lift(result, frames) - hand_lift(target, frames + 1)))
    assert up > 0.5 * drag[1], (up, drag)
    assert shown is not None and float(shown.group(2)) == pytest.approx(up, abs=0.006)
