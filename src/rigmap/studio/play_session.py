"""Play: a latent model driven live by the user's commands and by a game of noughts and
crosses, as the paper's demo (Bailey et al. 2016 §7), apart from any page.

One streaming thread owns a deadline clock (:class:`DeadlineClock`): each frame is computed
ahead (the controller's step, its used controls put into the rig's full row, the face's
mesh), then handed to ``publish`` at its deadline, ``start + k/fps`` (the Play page,
:mod:`rigmap.studio.play_page`, sends it to the browser there and then). The next deadline
is the last one plus ``1/fps``, never "now plus a frame", so the work a frame takes does
not slow the rate. A frame's lateness (handed over minus deadline) is kept for the
benchmark's p99. Each frame runs torch on one thread (``rigmap.torch_threads``: on the
2-core machine two threads made a step's p99 23 ms instead of 2.5 ms, measured).

The page's commands (its websocket's thread) are submitted under the lock the stream
steps under. The game: the user is X, the computer O (:func:`rigmap.latent.game.computer_move`:
win, else block, else a seeded random cell), replying ``reply_seconds`` after X so the
face has begun to react. Each move's event queues its emotion's commands
(:func:`rigmap.latent.game.emotion_commands`: TRANSITION to it if it is a model, PLAY one
of its takes); commands still waiting from before are dropped first (the one under way
finishes), so the face answers the newest event instead of a growing backlog (ours).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from rigmap.latent.errors import LatentInputError
from rigmap.latent.game import (
    EVENT_EMOTIONS,
    Board,
    GameError,
    computer_move,
    emotion_commands,
)
from rigmap.latent.particle import ParticleSettings
from rigmap.latent.synthesis import (
    Controller,
    Idle,
    Play,
    SynthesisSettings,
    Transition,
)
from rigmap.studio.scene import to_scene
from rigmap.torch_threads import one_thread

#: ours: O answers a second after X (the synth demo's 24 frames a turn)
REPLY_SECONDS = 1.0
#: ours: the state (status line, board) is published every 6th frame (4 a second) and on
#: every event
STATUS_EVERY = 6
#: ours: a stall longer than this restarts the deadlines instead of bursting to catch up
MAX_BEHIND_S = 0.5
#: ours: the frames whose lateness and controls are kept (5 minutes at 24 fps)
KEPT_FRAMES = 24 * 300
IDLE_FRAMES = 48  # ours: the IDLE button's default, two seconds


class DeadlineClock:
    """Deadlines ``t0 + k/fps``: :meth:`wait` sleeps to the next, :meth:`sent` records the
    frame's lateness and moves the deadline on by one period."""

    def __init__(
        self,
        fps: float,
        *,
        now: Callable[[], float] = time.perf_counter,
        max_behind: float = MAX_BEHIND_S,
        kept: int = KEPT_FRAMES,
    ):
        if not fps > 0:
            raise ValueError(f"fps must be positive, got {fps}")
        self.period = 1.0 / float(fps)
        self.now = now
        self.max_behind = max_behind
        self.lateness: deque[float] = deque(maxlen=kept)  # seconds, one per frame sent
        self.frames = 0
        self.slips = 0  # stalls after which the deadlines restarted
        self.deadline = float("nan")

    def start(self) -> None:
        """The first deadline one period from now (again after a pause)."""
        self.deadline = self.now() + self.period

    def wait(self, sleep: Callable[[float], bool]) -> bool:
        """Sleep until the deadline with ``sleep(seconds) -> stopped``; ``True`` if stopped."""
        remaining = self.deadline - self.now()
        return bool(sleep(remaining)) if remaining > 0 else False

    def sent(self) -> None:
        sent = self.now()
        self.lateness.append(sent - self.deadline)
        self.frames += 1
        self.deadline += self.period
        if sent - self.deadline > self.max_behind:
            self.deadline = sent + self.period
            self.slips += 1

    def summary(self) -> dict:
        """Frames, lateness p50/p99/max (ms) and frames later than a period."""
        late = 1e3 * np.array(self.lateness)
        if len(late) == 0:
            return {"frames": self.frames, "slips": self.slips}
        return {
            "frames": self.frames,
            "lateness_ms_p50": float(np.percentile(late, 50)),
            "lateness_ms_p99": float(np.percentile(late, 99)),
            "lateness_ms_max": float(late.max()),
            "frames_later_than_period": int((late > 1e3 * self.period).sum()),
            "slips": self.slips,
        }


def describe(command) -> str:
    """A command as the status line names it."""
    if isinstance(command, Transition):
        return f"TRANSITION to {command.model}"
    if isinstance(command, Play):
        return f"PLAY {command.take}"
    if isinstance(command, Idle):
        return f"IDLE {command.frames}"
    where = command.point if command.take is None else f"{command.take} frame {command.frame}"
    return f"MOVE to {where}"


class PlaySession:
    """Play over ``fitted`` (:class:`~rigmap.latent.library.FittedModels`) and ``table``
    (:class:`~rigmap.latent.transitions.TransitionTable`) of ``rig`` (a mesh rig: ``mesh``,
    ``faces``); ``fps`` is the clock's and the particle's rate. ``publish(kind, session)``
    hears ``"frame"`` (at each frame's deadline: :attr:`vertices`, :attr:`frame`) and
    ``"state"`` (the status, the board or the takes changed). The stream runs while
    :meth:`show` says a page shows it."""

    def __init__(self, rig, fitted, table, *, fps=24.0, seed=0, reply_seconds=REPLY_SECONDS):
        if not fitted.models:
            raise ValueError("Play needs at least one latent model")
        if not callable(getattr(rig, "mesh", None)) or getattr(rig, "faces", None) is None:
            raise ValueError(f"Play draws a mesh; rig {rig.name!r} has none")
        self.rig, self.fitted, self.table = rig, fitted, table
        self.fps = float(fps)
        start = "neutral" if "neutral" in fitted.models else next(iter(fitted.models))
        settings = SynthesisSettings(particle=ParticleSettings(fps=self.fps))
        self.controller = Controller(
            fitted.models,
            start=start,
            takes=fitted.sets,
            transitions=table,
            settings=settings,
            seed=seed,
        )
        self.rng = np.random.default_rng(seed)  # O's cells and the takes events play
        self.reply_frames = max(1, round(reply_seconds * self.fps))
        self.clock = DeadlineClock(self.fps)
        self.lock = threading.Lock()
        self.board = Board()
        self.expression = start  # the emotion of the last event (the start model before)
        self.events: list[dict] = []  # each game move: player, events, emotion, frame
        self.models: list[tuple[int, str]] = [(0, start)]  # (frame it began, model)
        self.played: deque[tuple[int, np.ndarray]] = deque(maxlen=KEPT_FRAMES)
        self.work: deque[float] = deque(maxlen=KEPT_FRAMES)  # seconds computing each frame
        self.message = ""  # the last refusal, one line
        self.publish: Callable[[str, PlaySession], None] = lambda kind, session: None
        self.vertices = to_scene(np.asarray(rig.mesh(rig.default_controls(1)))[0])
        self.frame = -1  # the frame whose vertices were published last
        self._reply_at: int | None = None  # the frame O moves on
        self._stop, self._visible = threading.Event(), threading.Event()
        self._thread = threading.Thread(target=self._stream, name="studio-play", daemon=True)
        self._thread.start()

    def show(self, visible: bool) -> None:
        """Stream only while a page shows it (paused: the clock starts again on resume)."""
        if visible:
            self._visible.set()
        else:
            self._visible.clear()

    def close(self) -> None:
        self._stop.set()
        self._visible.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)

    # ------------------------------------------------------------------ commands
    def command(self, command) -> bool:
        """Queue a user's command; a refused one's reason goes to the status line."""
        with self.lock:
            try:
                self.controller.submit(command)
                self.message = ""
            except LatentInputError as error:
                self.message = f"{type(command).__name__.upper()} refused: {error}"
        self.publish("state", self)
        return not self.message

    def take_names(self) -> list[str]:
        """The takes of the model the next command runs in (what PLAY and MOVE may name)."""
        with self.lock:
            return list(self.fitted.sets[self.controller.model_after_queue()].names)

    # ------------------------------------------------------------------ game
    def click_cell(self, cell: int) -> None:
        """X on ``cell`` (0-8, reading order); O answers ``reply_frames`` later."""
        with self.lock:
            try:
                kinds = self.board.play(cell, "x")
            except GameError as error:
                self.message = f"Cell {cell + 1}: {error}"
            else:
                self.message = ""
                self._react("x", kinds)
                if not self.board.over:
                    self._reply_at = self.controller.frame + self.reply_frames
        self.publish("state", self)

    def new_game(self) -> None:
        with self.lock:
            self.board, self._reply_at, self.message = Board(), None, ""
        self.publish("state", self)

    def _react(self, player: str, kinds: list[str]) -> None:
        """The face answers the move's last event (under the lock)."""
        emotion = EVENT_EMOTIONS[kinds[-1]]
        controller = self.controller
        controller.queue.clear()  # the waiting reactions to older events
        for command in emotion_commands(
            self.fitted, controller.model_after_queue(), emotion, self.rng
        ):
            controller.submit(command)
        self.expression = emotion
        self.events.append(
            {"player": player, "events": kinds, "emotion": emotion, "frame": controller.frame}
        )

    def _opponent_turn(self) -> bool:
        """O's move when it is due (under the lock); ``True`` if it moved."""
        if self._reply_at is None or self.controller.frame < self._reply_at:
            return False
        self._reply_at = None
        if self.board.over:
            return False
        self._react("o", self.board.play(computer_move(self.board, self.rng), "o"))
        return True

    # ------------------------------------------------------------------ stream
    def _stream(self) -> None:
        clock, paused = self.clock, True
        while not self._stop.is_set():
            if not self._visible.wait(timeout=0.2):
                paused = True
                continue
            if paused:
                clock.start()
                paused = False
            began = time.perf_counter()
            try:
                frame, controls, vertices, moved = self._next_frame()
            except Exception as error:  # shown in the page; the studio keeps serving
                with self.lock:
                    self.message = f"Play stopped: {type(error).__name__}: {error}"
                self.publish("state", self)
                return
            self.work.append(time.perf_counter() - began)
            if clock.wait(self._stop.wait):
                return
            self.vertices, self.frame = vertices, frame
            self.publish("frame", self)
            clock.sent()
            self.played.append((frame, controls))
            if moved or frame % STATUS_EVERY == 0:
                self.publish("state", self)

    def _next_frame(self):
        """``(frame, used controls, vertices in scene units, O moved)``, before its deadline."""
        rig = self.rig
        with one_thread():
            with self.lock:
                moved = self._opponent_turn()
                frame = self.controller.frame
                controls = self.controller.step()
                if self.controller.model != self.models[-1][1]:
                    self.models.append((frame, self.controller.model))
            full = rig.expand_used(controls)[None]
            vertices = to_scene(np.asarray(rig.mesh(full))[0]).astype(np.float32)
        return frame, controls, vertices, moved

    # ------------------------------------------------------------------ text
    def cell_labels(self) -> list[str]:
        """Each cell's label: a free cell its number (1-9), a taken one its mark."""
        with self.lock:
            cells = list(self.board.cells)
        return [str(k + 1) if mark is None else mark.upper() for k, mark in enumerate(cells)]

    def game_state(self) -> str:
        board = self.board
        winner = board.winner()
        if winner == "x":
            return "Game over: X wins (you)"
        if winner == "o":
            return "Game over: O wins (the computer)"
        if board.over:
            return "Game over: draw"
        return "X to play (you)" if board.turn == "x" else "O is thinking…"

    def status(self) -> str:
        """The status lines: the model, the frame, the command under way and those queued,
        the expression and the event behind it, the last refusal."""
        with self.lock:
            controller = self.controller
            active = controller._entry.command if controller._entry is not None else None
            queued = [describe(c) for c in controller.queue]
            line = f"{controller.model} · frame {controller.frame}"
            line += f" · now: {describe(active)}" if active is not None else " · idling"
            line += f" · queued: {', '.join(queued)}" if queued else " · nothing queued"
            last = self.events[-1] if self.events else None
            why = f" ({last['player'].upper()}: {', '.join(last['events'])})" if last else ""
            text = f"{line}\nExpression: {self.expression}{why}"
            if self.message:
                text += f"\n{self.message}"
        return text
