"""The studio's Play page (issue #43 item 4): a latent face driven at 24 fps by commands
and by a game of noughts and crosses against the user (Bailey et al. 2016 §7's demo).

The face's six game emotions are fitted small (4 PCA components, 2 latent dimensions,
25 L-BFGS iterations: a test-sized config, ours) in a temporary folder by the stage code.
Rates are the benchmark's (benchmarks/studio_play.py); here the clock is checked on a
fake time source, and the stream on what it sent. ``RIGMAP_SCREENSHOTS=docs/studio`` keeps
the browser test's page as ``docs/studio/play.png``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from rigmap.latent.game import EVENT_EMOTIONS, Board, GameError, computer_move, game_events
from rigmap.latent.synthesis import Play, Transition
from rigmap.studio.page_server import CommandError, PageServer, decode
from rigmap.studio.play_page import PlayChannel
from rigmap.studio.play_session import DeadlineClock, PlaySession
from rigmap.studio.scene import to_scene

ROOT = Path(__file__).resolve().parents[1]
EMOTIONS = sorted(set(EVENT_EMOTIONS.values()))  # every event's emotion is a model
TINY = [
    "rig=face",
    f"latent.labels=[{','.join(EMOTIONS)}]",
    "latent.n_pca=4",
    "latent.latent_dim=2",
    "latent.max_iter=25",
    "latent.match_max_iter=30",
    "latent.match_threshold_cm=0.5",
    "latent.log_to_mlflow=false",
]


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """``(rig, fitted, table)``: fit and match once (the stage code, in-process)."""
    from rigmap.app.latent import run_step
    from rigmap.cli import compose_config
    from rigmap.latent import steps
    from rigmap.rigs import load
    from rigmap.store import Layout

    tmp = tmp_path_factory.mktemp("play")
    paths = [f"paths.{k}={tmp / k}" for k in ("data", "models", "metrics", "reports")]
    for step in ("fit", "match"):
        run_step(compose_config([*TINY, *paths, f"+latent_step={step}"], ROOT / "conf"))
    layout = Layout.from_paths({k: str(tmp / k) for k in ("data", "models", "metrics")})
    return load("face"), steps.load_fitted(layout, "face"), steps.load_table(layout, "face")


def wait_for(condition, seconds: float, what: str):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.02)
    raise AssertionError(f"not within {seconds} s: {what}")


# ---------------------------------------------------------------------- clock and game
def test_the_clock_keeps_its_deadlines_whatever_each_frame_takes():
    """Deadlines stay ``t0 + k/fps`` (a slow frame is late, the next ones are not moved);
    a stall past ``max_behind`` restarts them once."""
    now = [100.0]
    clock = DeadlineClock(24.0, now=lambda: now[0], max_behind=0.5)
    period = 1 / 24

    def sleep(seconds):
        now[0] += seconds
        return False

    clock.start()
    for work in [0.01, 0.01, 1.5 * period, 0.0, 0.0, 0.01]:
        now[0] += work  # the frame's computation
        clock.wait(sleep)
        clock.sent()
    late = np.array(clock.lateness)
    # the third frame's work ends half a period past its deadline; the fourth is then due
    # already (sent at once, with the same lateness less a period) and the clock is back
    np.testing.assert_allclose(late, [0, 0, 0.5 * period, 0, 0, 0], atol=1e-12)
    assert clock.deadline == pytest.approx(100.0 + 7 * period)
    now[0] += 2.0  # a stall
    clock.sent()
    assert clock.slips == 1 and clock.deadline == pytest.approx(now[0] + period)
    assert clock.summary()["frames_later_than_period"] == 1


def test_the_game_reports_its_events_and_the_computer_blocks_and_wins():
    board = Board()
    assert board.play(0, "x") == ["own_move"]
    assert board.play(4, "o") == ["opponent_move"]
    assert board.play(1, "x") == ["own_move"]
    assert computer_move(board, np.random.default_rng(0)) == 2  # blocks X's top row
    assert board.play(2, "o") == ["threat"]  # O: 2, 4 and 6 free
    with pytest.raises(GameError, match="cell 2 is not free"):
        board.play(2, "x")
    board.play(3, "x")
    assert computer_move(board, np.random.default_rng(0)) == 6  # wins rather than blocks
    assert board.play(6, "o") == ["loss"] and board.over and board.winner() == "o"
    with pytest.raises(GameError, match="the game is over"):
        board.play(5, "x")
    events = [kind for seed in range(40) for _, kind in game_events(np.random.default_rng(seed))]
    assert {"own_move", "opponent_move", "threat", "win", "loss", "draw"} <= set(events)


# ---------------------------------------------------------------------- the stream
def test_the_stream_sends_the_controllers_frames_and_follows_commands(models):
    rig, fitted, table = models
    view = PlaySession(rig, fitted, table, seed=0)
    channel = PlayChannel(view)
    sent_messages = []
    channel.broadcast = lambda message, replaceable=False: sent_messages.append(message)
    view.show(True)  # as a page opening does
    started = time.perf_counter()
    try:
        wait_for(lambda: view.clock.frames >= 12, 10, "12 frames streamed")
        elapsed = time.perf_counter() - started
        assert view.clock.frames <= elapsed * 24 + 1  # never ahead of the clock
        view.show(False)  # hidden: the stream pauses, and resumes when shown
        paused = view.clock.frames
        time.sleep(0.5)
        assert view.clock.frames <= paused + 1
        view.show(True)
        wait_for(lambda: view.clock.frames >= paused + 4, 10, "the stream resumed")
        assert not view.command(Play("no such take"))
        assert "PLAY refused: unknown segment 'no such take'" in view.status()
        take = fitted.sets["roar"].names[1]
        assert view.command(Transition("roar")) and view.command(Play(take))
        assert view.take_names() == list(fitted.sets["roar"].names)
        with pytest.raises(CommandError, match="cell 9: expected 0-8"):
            channel.command({"type": "cell", "cell": 9})
        with pytest.raises(CommandError, match="idle: frames must be an integer >= 1"):
            channel.command({"type": "idle", "frames": "12; rm -rf /"})
        wait_for(
            lambda: any(isinstance(e.command, Play) for e in view.controller.log),
            60,
            "the PLAY finished",
        )
    finally:
        view.close()
    assert [m for _, m in view.models] == ["neutral", "roar"]
    (entry,) = [e for e in view.controller.log if isinstance(e.command, Play)]
    sent = dict(view.played)
    field = view.controller.fields["roar"]
    rows = fitted.sets["roar"].rows(take)
    expected = np.array([field.controls(x) for x in field.X[rows]])  # the take, a point a frame
    frames = range(entry.end - len(rows) + 1, entry.end + 1)
    np.testing.assert_allclose(np.array([sent[f] for f in frames]), expected, atol=1e-9)
    assert np.ptp(expected, axis=0).max() > 0.1  # the take moves the face
    last_frame, last_controls = view.played[-1]
    mesh = np.asarray(rig.mesh(rig.expand_used(last_controls)[None]))[0]
    frames = [decode(m) for m in sent_messages if decode(m)[0]["type"] == "frame"]
    header, points = frames[-1]
    assert header["frame"] == last_frame  # the page got the last frame played, as points
    np.testing.assert_allclose(points.reshape(-1, 3), to_scene(mesh), atol=1e-6)


# ---------------------------------------------------------------------- the browser
def _skin_pixels(png: bytes, width: int) -> int:
    """Pixels of the face's colour, lit or shaded (red over blue, not the white page), in
    the ``width`` leftmost columns."""
    import io

    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int64)[:, :width]
    red, green, blue = image[..., 0], image[..., 1], image[..., 2]
    return int(((red - blue > 12) & (red >= green) & (red < 250)).sum())


@pytest.mark.browser
def test_a_game_is_played_to_the_end_by_clicks_and_the_face_reacts(models):
    """Noughts and crosses by clicks in Chromium: the server's board decides each free
    cell, the page shows the end, every event changed the controller's expression."""
    from browser import chromium_page, keep_screenshot
    from rigmap.studio import probe

    rig, fitted, table = models
    view = PlaySession(rig, fitted, table, seed=3, reply_seconds=0.3)
    pages = PageServer({"play": PlayChannel(view)}, host="127.0.0.1", port=0)
    preference = [4, 0, 2, 6, 8, 1, 3, 5, 7]  # centre, corners, edges
    try:
        with chromium_page(viewport={"width": 1200, "height": 900}) as page:
            probe.watch_messages(page, "frame")  # what benchmarks/studio_play.py times
            page.goto(pages.links()["Play"])
            page.get_by_role("button", name="5", exact=True).wait_for(timeout=30_000)
            rest = np.array(view.vertices)
            clicks = 0
            while not view.board.over:
                wait_for(lambda: view.board.turn == "x" or view.board.over, 10, "X's turn")
                if view.board.over:
                    break
                cell = next(c for c in preference if c in view.board.free())
                page.get_by_role("button", name=str(cell + 1), exact=True).click()
                wait_for(lambda c=cell: view.board.cells[c] == "x", 10, f"X on cell {cell + 1}")
                clicks += 1
            page.get_by_text("Game over").wait_for(timeout=10_000)
            ended = page.get_by_text("Game over").inner_text()
            outcome = view.board.winner()
            assert ("X wins" if outcome == "x" else "O wins" if outcome else "draw") in ended
            last_event = view.events[-1]["events"][-1]
            assert last_event == {"x": "win", "o": "loss", None: "draw"}[outcome]
            wait_for(lambda: view.controller.model == EVENT_EMOTIONS[last_event], 30, "the end")
            wait_for(lambda: "now: PLAY" in view.status(), 30, "the end's take")
            time.sleep(0.3)  # into the take (~2 s): the screenshot shows the end's expression
            png = page.screenshot()
            left = int(page.locator("canvas").bounding_box()["width"])  # the panel's edge
            assert _skin_pixels(png, left) > 20_000  # the face is drawn, lit
            keep_screenshot(png, "play.png")  # docs/studio/play.png with RIGMAP_SCREENSHOTS
            updates = probe.messages_seen(page)
    finally:
        pages.stop()
    # the stream reached the page as face frames, each followed by a frame that drew it
    # (frames run their callbacks in order: every update before the last drawn one is drawn;
    # the newest may still wait for its frame when the page is read)
    drawn = ~np.isnan(updates[:, 1])
    last_drawn = int(np.flatnonzero(drawn).max())
    assert last_drawn + 1 > view.fps  # over a second of the game's frames
    assert drawn[: last_drawn + 1].all() and (updates[drawn, 1] >= updates[drawn, 0]).all()
    assert 3 <= clicks <= 5
    assert {e["player"] for e in view.events} == {"x", "o"}
    # the expression changed on the events: the first (X's move) began curious, the last
    # one's emotion is the model now, and every model after the start is an event's
    (_, start), (curious_frame, curious) = view.models[:2]
    assert (start, curious) == ("neutral", EVENT_EMOTIONS["own_move"])
    assert curious_frame >= view.events[0]["frame"]
    assert view.models[-1][1] == EVENT_EMOTIONS[last_event]
    assert {m for _, m in view.models[1:]} <= {e["emotion"] for e in view.events}
    assert np.abs(np.array(view.vertices) - rest).max() > 1e-3  # the face moved (m)
