"""Commands and a fixed-step controller over latent models (Bailey et al. 2016, §5.1–5.3).

The controller holds one particle in the current model's latent space. Commands queue
up and run one after another; ``step()`` advances one frame (1/24 s) and returns that
frame's used-control values (Eq 8's mean → PCA → unscale → clamp to the ranges):

- :class:`Move` — a path from the particle to a target (a latent point, or a training
  take's frame), a straight line or the shortest path through the training points
  (edge cost ``‖x_i − x_j‖^p``, ours: the paper's ``‖·‖^{−p}`` is the connectivity
  graph's affinity; as a path cost its inverse is what keeps hops short), resampled
  to a constant speed; done when the particle has settled within ``r`` of the target
  (and is slow enough for the wall to hold it, ours), or times out;
- :class:`Idle` — the path held at one point for a number of frames (the current
  path point by default, or a take's frame);
- :class:`Transition` — to another model: along the fewest-hops route of models, for
  each hop move to the bridge nearest the particle, start a particle in the next
  model at the bridge's other end, let both idle while the controls blend over 12
  frames (smoothstep), then carry on in the next model;
- :class:`Play` — a training take as it was embedded: move to its first latent point
  with the radius shrunk (ours: a quarter of ``r``), then place the particle on the
  take's latent points frame by frame.

With nothing queued the particle idles where its path ended. Every finished command
is logged (:attr:`Controller.log`) with its frames and whether it met its goal.
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.csgraph import dijkstra

from rigmap.latent.errors import LatentInputError
from rigmap.latent.particle import LatentField, Particle, ParticleSettings
from rigmap.latent.transitions import BLEND_FRAMES, TransitionTable, blend_weights

#: ours: how far past ``r`` (relative) a particle resting on the wall still counts as within
#: it — a thousand times the Baumgarte lag measured there (1e-5 of r), far below a pose change
WALL_TOLERANCE = 1e-3


@dataclass(frozen=True)
class Move:
    """Move to ``point`` (latent), or to frame ``frame`` of training take ``take``."""

    point: tuple[float, ...] | None = None
    take: str | None = None
    frame: int = 0
    path: str = "line"  # "line" or "graph"
    speed: float | None = None  # latent units per second; None: the settings'


@dataclass(frozen=True)
class Idle:
    frames: int
    take: str | None = None  # idle about this take's frame; None: where the path is
    frame: int = 0
    radius: float | None = None


@dataclass(frozen=True)
class Transition:
    model: str
    idle_frames: int = 0  # extra frames idling in the new model after the blend


@dataclass(frozen=True)
class Play:
    take: str


Command = Move | Idle | Transition | Play


@dataclass(frozen=True)
class SynthesisSettings:
    """All ours unless said."""

    particle: ParticleSettings = field(default_factory=ParticleSettings)
    speed: float = 1.5  # MOVE's path speed (latent units per second)
    graph_power: float = 4.0  # p of the path graph (the paper's 4)
    move_timeout_frames: int = 48  # extra frames a MOVE may take to come within r
    blend_frames: int = BLEND_FRAMES  # the paper's 12
    play_radius_fraction: float = 0.25  # r while approaching a PLAY segment's start


@dataclass
class LogEntry:
    command: Command
    model: str
    start: int  # first frame
    end: int = -1  # last frame
    success: bool = False
    switches: list[int] = field(default_factory=list)  # frames where a blend began

    @property
    def frames(self) -> int:
        return self.end - self.start + 1


class Controller:
    """``submit(command)``; ``step() → controls``. ``models`` maps names to fitted
    :class:`~rigmap.latent.LatentModel`; ``takes`` maps each model name to its
    :class:`~rigmap.latent.library.LabelledSet` (for commands that name a take)."""

    def __init__(
        self,
        models: Mapping,
        *,
        start: str,
        takes: Mapping | None = None,
        transitions: TransitionTable | None = None,
        settings: SynthesisSettings | None = None,
        seed: int = 0,
        start_point=None,
    ):
        if not models:
            raise LatentInputError("the controller needs at least one model")
        self.models = dict(models)
        self.takes = dict(takes or {})
        self.transitions = transitions
        self.settings = settings or SynthesisSettings()
        self.seed = int(seed)
        self.fields = {name: LatentField(m) for name, m in self.models.items()}
        self._check_model(start)
        self.model = start
        field0 = self.fields[start]
        x0 = field0.X[0] if start_point is None else np.asarray(start_point, dtype=np.float64)
        self._particles_made = 0
        self.particle = self._new_particle(start, x0)
        self.anchor = self.particle.x.copy()  # where the path is now
        self.frame = 0
        self.queue: deque[Command] = deque()
        self.log: list[LogEntry] = []
        self._active: Iterator[np.ndarray] | None = None
        self._entry: LogEntry | None = None

    # --- validation -------------------------------------------------------------
    def _check_model(self, name: str) -> None:
        if name not in self.models:
            raise LatentInputError(f"unknown model {name!r}; models: {sorted(self.models)}")

    def _take_rows(self, model: str, take: str) -> np.ndarray:
        entry = self.takes.get(model)
        if entry is None:
            raise LatentInputError(f"model {model!r} has no takes registered with the controller")
        if take not in entry.names:
            raise LatentInputError(
                f"unknown segment {take!r} in model {model!r}; segments: {entry.names}"
            )
        return entry.rows(take)

    def _take_point(self, model: str, take: str, frame: int) -> np.ndarray:
        rows = self._take_rows(model, take)
        if not 0 <= frame < len(rows):
            raise LatentInputError(
                f"segment {take!r} of model {model!r} has {len(rows)} frames; "
                f"frame {frame} is outside"
            )
        return self.fields[model].X[rows[frame]]

    def model_after_queue(self) -> str:
        """The model the next submitted command will run in: after the active command
        and every queued one (a TRANSITION under way counts as done)."""
        model = self.model
        active = [self._entry.command] if self._entry is not None else []
        for command in (*active, *self.queue):
            if isinstance(command, Transition):
                model = command.model
        return model

    _model_after_queue = model_after_queue

    def submit(self, command: Command) -> None:
        """Queue a command; names are checked now against the model it will run in."""
        model = self._model_after_queue()
        if isinstance(command, Move):
            if (command.point is None) == (command.take is None):
                raise LatentInputError("MOVE needs exactly one of point= or take=")
            if command.take is not None:
                self._take_point(model, command.take, command.frame)
            else:
                point = np.asarray(command.point, dtype=np.float64)
                if point.shape != (self.fields[model].q,) or not np.isfinite(point).all():
                    raise LatentInputError(
                        f"MOVE point must be {self.fields[model].q} finite numbers, "
                        f"got {command.point}"
                    )
            if command.path not in ("line", "graph"):
                raise LatentInputError(f"MOVE path must be 'line' or 'graph', got {command.path!r}")
        elif isinstance(command, Idle):
            if command.frames < 1:
                raise LatentInputError(f"IDLE needs ≥ 1 frame, got {command.frames}")
            if command.take is not None:
                self._take_point(model, command.take, command.frame)
        elif isinstance(command, Transition):
            self._check_model(command.model)
            if command.model != model:
                if self.transitions is None:
                    raise LatentInputError("TRANSITION needs a transition table (matching points)")
                self.transitions.route(model, command.model)
        elif isinstance(command, Play):
            self._take_rows(model, command.take)
        else:
            raise LatentInputError(f"not a command: {command!r}")
        self.queue.append(command)

    def run(
        self, commands, *, tail: int = 0, max_frames: int | None = None, progress: bool = False
    ) -> np.ndarray:
        """Submit ``commands`` and step until all are done, then ``tail`` more frames;
        the controls of every frame ``(F, C)``. A command is found finished on the step
        after its last frame, so the run ends with one idle frame past the last
        command (it is the controller's next frame, kept so runs join up). More than
        ``max_frames`` frames stop the run (``LatentInputError``); ``progress`` shows a bar."""
        from tqdm.auto import tqdm

        for command in commands:
            self.submit(command)
        frames = []
        with tqdm(desc="synthesis", unit="frame", disable=not progress, leave=False) as bar:
            while self.queue or self._active is not None:
                if max_frames is not None and len(frames) >= max_frames:
                    playing = "" if self._entry is None else f" in {self._entry.command!r}"
                    raise LatentInputError(
                        f"the commands go on past {max_frames} frames "
                        f"(latent.max_script_frames); stopped at frame {len(frames)}{playing}"
                    )
                frames.append(self.step())
                bar.update()
        frames.extend(self.step() for _ in range(tail))
        return np.array(frames)

    @property
    def busy(self) -> bool:
        return bool(self.queue) or self._active is not None

    # --- stepping ------------------------------------------------------------------
    def step(self) -> np.ndarray:
        """One frame: the active command's, else the next queued one's, else idling."""
        while True:
            if self._active is None and self.queue:
                command = self.queue.popleft()
                self._entry = LogEntry(command, self.model, self.frame)
                self._active = self._plan(command)
            if self._active is None:
                controls = self._idle_frame(self.anchor)
                break
            try:
                controls = next(self._active)
                break
            except StopIteration:
                self._finish_entry(self.frame - 1)
        self.frame += 1
        return controls

    def _finish_entry(self, last: int) -> None:
        entry = self._entry
        entry.end = max(last, entry.start)
        self.log.append(entry)
        self._active, self._entry = None, None

    def _new_particle(self, model: str, x0) -> Particle:
        self._particles_made += 1
        seed = np.random.SeedSequence([self.seed, self._particles_made]).generate_state(1)[0]
        t0 = self.particle.t if hasattr(self, "particle") else 0.0
        return Particle(
            self.fields[model], x0, settings=self.settings.particle, seed=int(seed), t0=t0
        )

    def _advance(self, p0, p1) -> np.ndarray:
        self.particle.step(p0, p1)
        self.anchor = np.asarray(p1, dtype=np.float64).copy()
        return self.fields[self.model].controls(self.particle.x)

    def _idle_frame(self, point) -> np.ndarray:
        return self._advance(point, point)

    def _plan(self, command: Command) -> Iterator[np.ndarray]:
        if isinstance(command, Move):
            target = (
                np.asarray(command.point, dtype=np.float64)
                if command.point is not None
                else self._take_point(self.model, command.take, command.frame)
            )
            return self._move(target, command.path, command.speed)
        if isinstance(command, Idle):
            return self._idle(command)
        if isinstance(command, Transition):
            return self._transition(command)
        return self._play(command)

    # --- MOVE --------------------------------------------------------------------
    def path_points(self, start, target, kind: str = "line", speed: float | None = None):
        """Path points, one per frame, from ``start`` to ``target`` at constant speed."""
        speed = speed or self.settings.speed
        if kind == "graph":
            X = self.fields[self.model].X
            nodes = np.vstack([start, target, X])
            D = np.sqrt(((nodes[:, None] - nodes[None]) ** 2).sum(-1))
            cost = D**self.settings.graph_power
            _, pred = dijkstra(cost, directed=False, indices=0, return_predecessors=True)
            chain = [1]
            while chain[-1] != 0:
                chain.append(int(pred[chain[-1]]))
            polyline = nodes[chain[::-1]]
        else:
            polyline = np.vstack([start, target])
        seg = np.sqrt(((np.diff(polyline, axis=0)) ** 2).sum(1))
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        length = arc[-1]
        step = speed / self.settings.particle.fps
        n = max(1, int(np.ceil(length / step)))
        s = np.linspace(0.0, length, n + 1)[1:]
        return np.stack([np.interp(s, arc, polyline[:, k]) for k in range(polyline.shape[1])], 1)

    def _move(self, target, kind="line", speed=None, radius=None) -> Iterator[np.ndarray]:
        particle = self.particle
        old_radius = particle.radius
        if radius is not None:
            particle.radius = radius
        try:
            previous = self.anchor
            for point in self.path_points(self.anchor, target, kind, speed):
                yield self._advance(previous, point)
                previous = point
            reach = particle.radius
            for _ in range(self.settings.move_timeout_frames):
                if self._settled(target, reach):
                    break
                yield self._advance(target, target)
            if self._entry is not None and isinstance(self._entry.command, Move):
                self._entry.success = self._settled(target, reach)
        finally:
            particle.radius = old_radius

    def _settled(self, target, reach) -> bool:
        """Within ``reach`` of ``target`` (to :data:`WALL_TOLERANCE`) and slow enough for the
        wall's shell to stop it, ``‖v‖ ≤ α (1 − shell) reach`` (ours), so what follows starts
        inside the radius.

        The tolerance matters: once the path has stopped, the random force drifts the
        particle until it rests on the wall, where Baumgarte's term holds ``‖x − p‖ − r``
        at a small positive lag behind the changing force (measured: 1e-6 latent units,
        1e-5 of r, for seconds on end). A strict ``≤ r`` failed such a resting particle
        until the MOVE timed out (the quick face's MOVE suite, seed 2: 1 of 6; before the
        post-stabilisation of :meth:`Particle.step`, 2 of 6 on seed 0)."""
        p, s = self.particle, self.settings.particle
        slow = float(np.linalg.norm(p.v)) <= s.alpha * (1.0 - s.shell) * reach
        return bool(slow and np.linalg.norm(p.x - target) <= (1.0 + WALL_TOLERANCE) * reach)

    # --- IDLE --------------------------------------------------------------------
    def _idle(self, command: Idle) -> Iterator[np.ndarray]:
        if command.take is not None:
            point = self._take_point(self.model, command.take, command.frame)
            yield from self._move(point)
        point = self.anchor.copy()
        particle = self.particle
        old = particle.radius
        if command.radius is not None:
            particle.radius = command.radius
        worst = 0.0
        try:
            for _ in range(command.frames):
                controls = self._idle_frame(point)
                worst = max(worst, float(np.linalg.norm(particle.x - point)))
                yield controls
        finally:
            particle.radius = old
        self._entry.success = worst <= 1.05 * (command.radius or old)

    # --- TRANSITION --------------------------------------------------------------
    def _transition(self, command: Transition) -> Iterator[np.ndarray]:
        route = (
            self.transitions.route(self.model, command.model)
            if command.model != self.model
            else [self.model]
        )
        weights = blend_weights(self.settings.blend_frames)
        for a, b in itertools.pairwise(route):
            x_a, x_b, _ = self.transitions.nearest(a, b, self.particle.x)
            yield from self._move(x_a)
            incoming = self._new_particle(b, x_b)
            field_b = self.fields[b]
            self._entry.switches.append(self.frame)
            for w in weights:
                out_a = self._idle_frame(x_a)
                incoming.step(x_b, x_b)
                yield (1.0 - w) * out_a + w * field_b.controls(incoming.x)
            self.model, self.particle, self.anchor = b, incoming, x_b.copy()
        for _ in range(command.idle_frames):
            yield self._idle_frame(self.anchor)
        self._entry.success = self.model == command.model

    # --- PLAY ----------------------------------------------------------------------
    def _play(self, command: Play) -> Iterator[np.ndarray]:
        rows = self._take_rows(self.model, command.take)
        X = self.fields[self.model].X[rows]
        r = self.settings.particle.radius * self.settings.play_radius_fraction
        yield from self._move(X[0], radius=r)
        reached = np.linalg.norm(self.particle.x - X[0]) <= 1.05 * r
        fps = self.settings.particle.fps
        field_m = self.fields[self.model]
        for k in range(len(X)):
            # at rest on the first and last frame (ours: takes start and end near rest, and
            # a take's last velocity would carry the particle out of what follows' radius)
            v = (X[k] - X[k - 1]) * fps if 0 < k < len(X) - 1 else np.zeros_like(X[0])
            self.particle.place(X[k], v)
            self.anchor = X[k].copy()
            yield field_m.controls(X[k])
        self._entry.success = bool(reached)
