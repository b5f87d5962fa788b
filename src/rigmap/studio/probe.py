"""Driving the studio's pages from a real browser as a user does, and timing it there:
shared by the browser tests and ``benchmarks/studio*.py`` (Playwright pages; nothing here
runs in the studio itself).

A drag is real mouse input (Chromium's own pointer events) on the Pose page's handle or a
viser gizmo's axis arrow, found on the canvas from the page's camera
(:func:`rigmap.studio.camera.screen_point`). Latency is
measured in the page's clock: from the ``pointermove`` event's time stamp to the animation
frame in which the page first shows the pose it caused (the status line's pose count), timed
when that frame's callbacks run (a frame's own time stamp is its start, which can precede
the update by a frame or more on a busy page).
"""

from __future__ import annotations

import re

import numpy as np

from rigmap.studio.camera import screen_point
from rigmap.studio.scene import to_scene

#: where on an axis arrow the mouse grabs it, as a share of the gizmo's scale (measured: the
#: arrow's shaft is grabbed at 0.8; at 0.6 the press can miss it and orbit the camera)
ARROW_GRAB = 0.8
STATUS = re.compile(r"pose (\d+) ·")

WATCH_POSES = """(marker) => {
  const node = [...document.querySelectorAll('p')].find((n) => n.textContent.includes(marker));
  if (!node) { throw new Error('no status line holding ' + marker); }
  const box = node.parentElement.parentElement;
  window.__moves = []; window.__frames = [];
  window.addEventListener('pointermove', (e) => window.__moves.push(e.timeStamp), true);
  let last = -1;
  const seen = () => {
    const m = box.textContent.match(/pose (\\d+) ·/);
    const n = m ? Number(m[1]) : -1;
    if (n !== last) {
      last = n;
      requestAnimationFrame(() => window.__frames.push([n, performance.now()]));
    }
  };
  new MutationObserver(seen).observe(box, {subtree: true, childList: true, characterData: true});
  seen();
}"""


def canvas_box(page) -> dict:
    page.wait_for_selector("canvas", timeout=60_000)
    return page.locator("canvas").first.bounding_box()


def gizmo_point(view, joint: str, box: dict, *, along=(1.0, 0.0, 0.0)) -> tuple[float, float]:
    """The page pixel of ``joint``'s gizmo arrow (``along`` one of its axes) in a viser view."""
    gizmo = view.gizmo(joint)
    point = np.asarray(gizmo.position) + ARROW_GRAB * view.gizmo_scale * np.asarray(along)
    x, y = screen_point(view.camera, point, box["width"], box["height"])
    return box["x"] + x, box["y"] + y


def handle_point(pose_page, effector: str, box: dict) -> tuple[float, float]:
    """The page pixel of ``effector``'s handle on the Pose page (its target, drawn where the
    page's camera sees it)."""
    driver = pose_page.driver
    target = to_scene(driver.targets[driver.session.effectors.index(effector)])
    x, y = screen_point(pose_page.camera, target, box["width"], box["height"])
    return box["x"] + x, box["y"] + y


def watch_poses(page, marker: str = "effectors · pose") -> None:
    """Start recording pointer moves and the frames that show a new pose."""
    page.wait_for_function(
        "(m) => document.body.textContent.includes(m)", arg=marker, timeout=60_000
    )
    page.evaluate(WATCH_POSES, marker)


def frames_seen(page) -> int:
    return int(page.evaluate("window.__frames.length"))


#: viser's gizmo (the Edit view's) sends at most one update per 50 ms while dragging (its
#: client's throttle): a move sooner than that waits in the page. Drags are paced just above
#: it (ours); the Pose page sends every move, and is timed at the same pace as before.
PACE_S = 0.06


def timed_drag(page, start, steps, *, pace_s: float = PACE_S, timeout_ms: float = 10_000):
    """Press at ``start``, move through ``steps`` (page pixels) at most one move per
    ``pace_s``, waiting after each for the frame that shows its pose; release.
    Milliseconds per move, from its pointer event to that frame (the page's clock)."""
    import time

    page.mouse.move(*start)
    page.mouse.down()
    latencies, last = [], 0.0
    try:
        for x, y in steps:
            before = frames_seen(page)
            time.sleep(max(0.0, last + pace_s - time.perf_counter()))
            last = time.perf_counter()
            page.mouse.move(x, y)
            page.wait_for_function(
                "(n) => window.__frames.length > n", arg=before, timeout=timeout_ms
            )
            moved, shown = page.evaluate("[window.__moves.at(-1), window.__frames.at(-1)[1]]")
            latencies.append(float(shown - moved))
    finally:
        page.mouse.up()
    return latencies


def wiggle(start, n: int, *, step_px: float = 2.0, span: int = 10) -> list[tuple[float, float]]:
    """``n`` points moving right by ``step_px`` and back every ``span`` steps (a hand
    nudging an effector to and fro, staying on the screen)."""
    x0, y0 = start
    phases = [k % (2 * span) for k in range(1, n + 1)]
    return [(x0 + step_px * min(p, 2 * span - p), y0) for p in phases]


#: Installed before the page's scripts run (``page.add_init_script``): records, in the
#: page's clock, when each message of a studio page's websocket whose header is of ``KIND``
#: reached the page and the animation frame that follows it (the first frame able to show
#: it). The header is read as rigmap.studio.page_server.encode writes it.
WATCH_MESSAGES = """(() => {
  window.__messages = [];
  const NativeSocket = window.WebSocket;
  window.WebSocket = class extends NativeSocket {
    constructor(...args) {
      super(...args);
      this.addEventListener('message', (event) => {
        if (!(event.data instanceof ArrayBuffer)) { return; }
        const size = new DataView(event.data).getUint32(0, true);
        const text = new TextDecoder().decode(new Uint8Array(event.data, 4, size));
        if (JSON.parse(text).type !== KIND) { return; }
        const entry = [performance.now(), null];
        window.__messages.push(entry);
        requestAnimationFrame(() => { entry[1] = performance.now(); });
      });
    }
  };
})();"""


def watch_messages(page, kind: str) -> None:
    """Record when each message of ``kind`` (``frame``: Play's) reaches the page; call before
    the page loads (see :data:`WATCH_MESSAGES`)."""
    import json

    page.add_init_script(script=WATCH_MESSAGES.replace("KIND", json.dumps(kind)))


def messages_seen(page, *, clear: bool = False) -> np.ndarray:
    """``(N, 2)`` page times (ms) of the watched messages so far: reached the page, next
    frame (NaN until drawn); ``clear`` starts a new record."""
    rows = page.evaluate(
        "(clear) => { const rows = window.__messages.slice();"
        " if (clear) { window.__messages.length = 0; } return rows; }",
        clear,
    )
    return np.array([[a, np.nan if f is None else f] for a, f in rows], dtype=np.float64).reshape(
        -1, 2
    )


def schedule_lateness(times_ms: np.ndarray, period_ms: float) -> np.ndarray:
    """How late each of a stream's frames came against a steady ``period_ms`` schedule
    anchored on the stream's earliest frame: ``t_k - k * period`` minus its minimum."""
    slots = np.asarray(times_ms, dtype=np.float64) - period_ms * np.arange(len(times_ms))
    return slots - slots.min()
