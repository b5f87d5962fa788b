"""The Play view: a latent model driven live by the user's commands and by a game of
noughts and crosses, as the paper's demo (Bailey et al. 2016 §7).

One streaming thread owns a deadline clock (:class:`DeadlineClock`): each frame is computed
ahead (the controller's step, its used controls put into the rig's full row, the face's
mesh), then handed to viser at its deadline, ``start + k/fps``. The next deadline is the
last one plus ``1/fps``, never "now plus a frame", so the work a frame takes does not slow
the rate. A frame's lateness (handed over minus deadline) is kept for the benchmark's p99.
"Handed over" is the mesh update queued on viser's websocket; the socket write happens on
viser's event loop. Each frame runs torch on one thread (``rigmap.torch_threads``: on the
2-core machine two threads made a step's p99 23 ms instead of 2.5 ms, measured).

The GUI's callbacks (viser's thread pool) submit commands under the lock the stream steps
under. The game: the user is X, the computer O (:func:`rigmap.latent.game.computer_move`:
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
    Move,
    Play,
    SynthesisSettings,
    Transition,
)
from rigmap.studio.camera import aim_every_page, front_camera
from rigmap.studio.scene import add_surface, to_scene
from rigmap.torch_threads import one_thread

SCENE = "/play"
FACE_NODE = f"{SCENE}/face"  # the face's mesh in the scene
FACE_COLOR = (225, 190, 170)  # as the Pose view's
#: ours: O answers a second after X (the synth demo's 24 frames a turn)
REPLY_SECONDS = 1.0
#: ours: the status line is rewritten every 6th frame (4 a second) and on every event
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


class PlayView:
    """The view over ``fitted`` (:class:`~rigmap.latent.library.FittedModels`) and
    ``table`` (:class:`~rigmap.latent.transitions.TransitionTable`) of ``rig`` (a mesh
    rig: ``mesh``, ``faces``); ``fps`` is the clock's and the particle's rate."""

    name = "Play"

    def __init__(self, rig, fitted, table, *, fps=24.0, seed=0, reply_seconds=REPLY_SECONDS):
        if not fitted.models:
            raise ValueError("the Play view needs at least one latent model")
        if not callable(getattr(rig, "mesh", None)) or getattr(rig, "faces", None) is None:
            raise ValueError(f"the Play view draws a mesh; rig {rig.name!r} has none")
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
        self._reply_at: int | None = None  # the frame O moves on
        self._stop, self._visible = threading.Event(), threading.Event()
        self._thread = threading.Thread(target=self._stream, name="studio-play", daemon=True)
        self.mesh = None

    # ------------------------------------------------------------------ page
    def build(self, server, gui) -> None:
        self.server = server
        rig = self.rig
        rest = to_scene(np.asarray(rig.mesh(rig.default_controls(1)))[0])
        self.camera = front_camera(rest)
        self.mesh = add_surface(server.scene, FACE_NODE, rest, rig.faces, FACE_COLOR)
        self.status = gui.add_markdown("")
        with gui.add_folder("Commands"):
            self._build_commands(gui)
        with gui.add_folder("Noughts and crosses"):
            self.board_text = gui.add_markdown("")
            self.rows = [
                gui.add_button_group(f"Row {r + 1}", options=self._row_labels(r)) for r in range(3)
            ]
            self.new_game_button = gui.add_button("New game")
        for r, row in enumerate(self.rows):
            row.on_click(lambda event, r=r: self._cell_clicked(r, event.target.value))
        self.new_game_button.on_click(lambda _event: self.new_game())
        self._show_board()
        self._show_status()
        self._thread.start()

    def _build_commands(self, gui) -> None:
        model = self.controller.model
        self.model_menu = gui.add_dropdown("Model", options=list(self.fitted.models))
        self.model_menu.value = model
        self.transition_button = gui.add_button("TRANSITION")
        self.take_menu = gui.add_dropdown("Take", options=self.fitted.sets[model].names)
        self.play_button = gui.add_button("PLAY")
        self.frame_input = gui.add_number("Frame", initial_value=0, min=0, step=1)
        self.move_button = gui.add_button("MOVE")
        self.idle_input = gui.add_number("Idle frames", initial_value=IDLE_FRAMES, min=1, step=1)
        self.idle_button = gui.add_button("IDLE")
        self.transition_button.on_click(
            lambda _event: self.command(Transition(self.model_menu.value))
        )
        self.play_button.on_click(lambda _event: self.command(Play(self.take_menu.value)))
        self.move_button.on_click(
            lambda _event: self.command(
                Move(take=self.take_menu.value, frame=int(self.frame_input.value))
            )
        )
        self.idle_button.on_click(lambda _event: self.command(Idle(int(self.idle_input.value))))

    def show(self, visible: bool) -> None:
        """Stream only while shown; a shown view puts every page's camera on the face."""
        if self.mesh is not None:
            self.mesh.visible = visible
        if not visible:
            self._visible.clear()
            return
        aim_every_page(self.camera, self.server)
        self._visible.set()

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
        self._show_takes()
        self._show_status()
        return not self.message

    def _show_takes(self) -> None:
        """The Take menu lists the takes of the model the next command runs in."""
        with self.lock:
            names = tuple(self.fitted.sets[self.controller.model_after_queue()].names)
        if tuple(self.take_menu.options) != names:
            self.take_menu.options = names

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
        self._show_board()
        self._show_takes()
        self._show_status()

    def _cell_clicked(self, row: int, label: str) -> None:
        if label.isdigit():
            self.click_cell(int(label) - 1)
        else:
            with self.lock:
                self.message = f"Row {row + 1}: that cell is taken"
            self._show_status()

    def new_game(self) -> None:
        with self.lock:
            self.board, self._reply_at, self.message = Board(), None, ""
        self._show_board()
        self._show_status()

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
                self.status.content = f"**Play stopped**: {type(error).__name__}: {error}"
                return
            self.work.append(time.perf_counter() - began)
            if clock.wait(self._stop.wait):
                return
            self.mesh.vertices = vertices
            self.server.flush()  # on its deadline, not at the next of viser's 1/60 s windows
            clock.sent()
            self.played.append((frame, controls))
            if moved:
                self._show_board()
                self._show_takes()
            if moved or frame % STATUS_EVERY == 0:
                self._show_status()

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
    def _row_labels(self, row: int) -> tuple[str, ...]:
        """A free cell is labelled by its number (1-9), a taken one by its mark."""
        cells = self.board.cells[3 * row : 3 * row + 3]
        return tuple(
            str(3 * row + k + 1) if mark is None else mark.upper() for k, mark in enumerate(cells)
        )

    def game_state(self) -> str:
        board = self.board
        winner = board.winner()
        if winner == "x":
            return "Game over: **X wins** (you)"
        if winner == "o":
            return "Game over: **O wins** (the computer)"
        if board.over:
            return "Game over: **draw**"
        return "**X to play** (you)" if board.turn == "x" else "O is thinking…"

    def _show_board(self) -> None:
        with self.lock:
            labels = [self._row_labels(r) for r in range(3)]
            state = self.game_state()
        for row, options in zip(self.rows, labels, strict=True):
            if tuple(row.options) != options:
                row.options = options
        grid = "\n---+---+---\n".join(" " + " | ".join(cells) for cells in labels)
        self.board_text.content = f"```\n{grid}\n```\n\n{state}"

    def _show_status(self) -> None:
        with self.lock:
            controller = self.controller
            active = controller._entry.command if controller._entry is not None else None
            queued = [describe(c) for c in controller.queue]
            line = f"**{controller.model}** · frame {controller.frame}"
            line += f" · now: {describe(active)}" if active is not None else " · idling"
            line += f" · queued: {', '.join(queued)}" if queued else " · nothing queued"
            last = self.events[-1] if self.events else None
            why = f" ({last['player'].upper()}: {', '.join(last['events'])})" if last else ""
            text = f"{line}\n\nExpression: **{self.expression}**{why}"
            if self.message:
                text += f"\n\n{self.message}"
        self.status.content = text
