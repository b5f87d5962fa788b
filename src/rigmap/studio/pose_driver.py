"""Posing a rig from dragged effectors, apart from any page (Holden et al. 2017, Figs 5, 6,
10: full-body IK, feet only, FaceIK).

A drag sends a stream of effector targets; the driver keeps only the newest and one worker
thread poses them (a pose takes ~5-30 ms, drags arrive faster), so the rig follows the hand
instead of a growing queue. Each pose reached is handed to ``publish``; the page that shows
it (:mod:`rigmap.studio.pose_page`) is a listener, so the posing is tested without one.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from rigmap.studio.scene import has_surface, world_pose
from rigmap.studio.writes import OutputFolder
from rigmap.torch_threads import single_threaded

#: the controls listed in the page: the most moved from rest (the export has every one); ours
LISTED_CONTROLS = 16
#: a pose's .blend plays at this rate (one frame; ours: the corpus's)
POSE_FPS = 24.0
#: the warm-up's second pose moves the effectors this far (cm; ours: a small drag)
WARM_UP_NUDGE_CM = 0.5
#: the newest poses' times kept (ms; a long session does not grow them; ours)
POSE_TIMES_KEPT = 2048


@dataclass
class PoseSession:
    """A rig ready to be posed: ``pose(targets (K, 3) cm) -> (controls (C,), distance cm,
    joints (J, 3) cm or None)`` for the ``effectors`` joints (the joints when the posing
    evaluated them anyway); ``reset()`` starts a new drag; ``rest`` the first pose."""

    rig: object
    effectors: tuple[str, ...]
    pose: Callable[[np.ndarray], tuple[np.ndarray, float, np.ndarray | None]]
    reset: Callable[[], None]
    rest: np.ndarray
    description: str = ""


@dataclass
class PoseRecord:
    """The newest pose: its count, controls, joints and surface (cm), distance, and the
    newest poses' times (ms)."""

    count: int = 0
    controls: np.ndarray | None = None
    joints: np.ndarray | None = None
    surface: np.ndarray | None = None
    distance_cm: float = float("nan")
    pose_ms: deque[float] = field(default_factory=lambda: deque(maxlen=POSE_TIMES_KEPT))


class PoseDriver:
    """The rigs offered (``sessions``: a name to a factory called when it is picked), the
    current one's effector targets (cm) and the worker that poses them. ``publish(kind,
    driver)`` hears ``"rig"`` (a rig was loaded), ``"pose"`` (a pose was reached) and
    ``"status"`` (a message in :attr:`status`)."""

    def __init__(
        self,
        sessions: Mapping[str, Callable[[], PoseSession]],
        out: OutputFolder,
        publish: Callable[[str, PoseDriver], None] = lambda kind, driver: None,
    ):
        if not sessions:
            raise ValueError("the Pose view needs at least one rig")
        self.factories = dict(sessions)
        self.out = out
        self.publish = publish
        self.session: PoseSession | None = None
        self.record = PoseRecord()
        self.targets: np.ndarray | None = None  # (K, 3) cm, where the user put the effectors
        self.status = "Pick a rig."
        self._pending: np.ndarray | None = None
        self._new_drag = False
        self._stop = False
        self._wake = threading.Condition()
        self._loading = threading.Lock()
        # one rig call at a time: a rig loading warms up while the worker may still pose the
        # last one, and the thread settings (single_threaded) are the process's, not a thread's
        self._rig_calls = threading.Lock()
        self._worker = threading.Thread(target=self._pose_loop, name="studio-pose", daemon=True)
        self._worker.start()

    @property
    def rig_names(self) -> list[str]:
        return list(self.factories)

    # ------------------------------------------------------------------ rig
    def load(self, rig_name: str) -> None:
        """The rig ``rig_name`` at its rest pose, its effectors' targets on its joints."""
        if rig_name not in self.factories:
            self._say(f"{rig_name!r}: not one of the studio's rigs ({', '.join(self.factories)})")
            return
        with self._loading:
            self._say(f"Loading {rig_name}: fitting or reading its effector mapping…")
            try:
                session = self.factories[rig_name]()
            except Exception as error:  # shown in the page; the studio keeps serving
                self._say(f"{rig_name}: {error}")
                return
            names = list(session.rig.joint_names)
            # warm: a drag's first poses trace the rig (0.7 s on the biped) and set up the
            # carried Jacobian's step (0.4 s)
            with self._rig_calls, single_threaded():
                joints, surface = world_pose(session.rig, session.rest)
                targets = joints[[names.index(j) for j in session.effectors]].copy()
                session.pose(targets)
                session.pose(targets + WARM_UP_NUDGE_CM)
                session.reset()
            with self._wake:
                self._pending = None
                self.session = session
                self.targets = targets
                self.record = PoseRecord(
                    controls=session.rest.copy(), joints=joints, surface=surface, distance_cm=0.0
                )
                self.status = self._status_line(0.0)
            self.publish("rig", self)

    # ------------------------------------------------------------------ drags
    def drag(self, effector: str, target_cm, *, phase: str = "move") -> None:
        """Effector ``effector`` moved to ``target_cm`` (3,); ``phase`` ``start`` begins a new
        drag (the refinement restarts from the mapping's guess), ``end`` finishes one."""
        with self._wake:
            session = self.session
            if session is None:
                raise ValueError("no rig is loaded")
            if effector not in session.effectors:
                raise ValueError(f"{effector!r}: not an effector of {session.rig.name}")
            target = np.asarray(target_cm, dtype=np.float64)
            if target.shape != (3,) or not np.isfinite(target).all():
                raise ValueError(f"{effector}: a target is three finite numbers, got {target_cm!r}")
            if phase == "start":
                self._new_drag = True  # the worker resets between poses, never under one
            k = session.effectors.index(effector)
            if np.array_equal(self.targets[k], target):
                return  # a press, or a release where the last move left it: nothing to pose
            self.targets[k] = target
            self._pending = self.targets.copy()
            self._wake.notify()

    def _pose_loop(self) -> None:
        while True:
            with self._wake:
                while self._pending is None and not self._stop:
                    self._wake.wait()
                if self._stop:
                    return
                targets, self._pending = self._pending, None
                session, new_drag, self._new_drag = self.session, self._new_drag, False
            started = time.perf_counter()
            try:
                with self._rig_calls, single_threaded():
                    if new_drag:
                        session.reset()
                    controls, distance, joints = session.pose(targets)
                    surface = None
                    if joints is None or has_surface(session.rig):
                        joints, surface = world_pose(session.rig, controls)
            except Exception as error:  # shown in the page; the next drag tries again
                self._say(f"{session.rig.name}: posing failed: {error}")
                continue
            seconds = time.perf_counter() - started
            with self._wake:  # a rig loaded meanwhile swaps session and record under it
                if session is not self.session:  # another rig was picked: not its pose
                    continue
                record = self.record
                record.count += 1
                record.controls = np.asarray(controls, dtype=np.float64)
                record.joints, record.surface = joints, surface
                record.distance_cm = float(distance)
                record.pose_ms.append(1e3 * seconds)
                self.status = self._status_line(seconds)
            self.publish("pose", self)

    def _status_line(self, seconds: float) -> str:
        session, record = self.session, self.record
        return (
            f"{session.rig.name} · {len(session.effectors)} effectors · pose {record.count} · "
            f"{record.distance_cm:.2f} cm from the targets · {1e3 * seconds:.0f} ms"
        )

    def _say(self, message: str) -> None:
        self.status = message
        self.publish("status", self)

    def close(self) -> None:
        with self._wake:
            self._stop = True
            self._wake.notify()

    # ------------------------------------------------------------------ results
    def listing(self) -> list[tuple[str, float]]:
        """The controls most moved from rest (none at rest): ``(name, value)`` rows."""
        session, record = self.session, self.record
        if session is None or record.controls is None:
            return []
        rig, controls = session.rig, record.controls
        used = np.asarray(rig.controls.used_indices)
        moved = np.abs(controls[used] - session.rest[used])
        order = np.argsort(-moved, kind="stable")[:LISTED_CONTROLS]
        return [(rig.control_names[used[i]], float(controls[used[i]])) for i in order if moved[i]]

    def export(self, kind: str = "json") -> str:
        """The pose under the output folder; returns its name there. ``json``: the effector
        targets and every used control; ``blend``: the used controls keyed at frame 1 in a
        .blend (a Blender rig's keys, or a mesh rig's shape keys; a rig with neither is
        refused with its reason)."""
        session, record = self.session, self.record
        if session is None or record.controls is None:
            raise ValueError("no rig is loaded")
        rig = session.rig
        used = rig.controls.used_indices
        name = f"pose/{rig.name.replace(':', '_')}-{record.count}"
        if kind == "blend":
            import pandas as pd

            from rigmap.rigs.blender.writers import blend_writer

            writer = blend_writer(rig)  # before any file: a rig with no .blend form
            table = pd.DataFrame(record.controls[None, used], columns=list(rig.used_controls))
            table.insert(0, "frame", [1])
            path = self.out.path(f"{name}.blend")
            writer(rig, table, path, fps=POSE_FPS, action_name=f"{rig.name}_pose")
            return self.out.relative(path)
        if kind != "json":
            raise ValueError(f"export {kind!r}: expected json or blend")
        document = {
            "rig": rig.name,
            "effectors": {
                j: t.tolist() for j, t in zip(session.effectors, self.targets, strict=True)
            },
            "target_distance_rms_cm": record.distance_cm,
            "used_controls": dict(
                zip(rig.used_controls, record.controls[used].tolist(), strict=True)
            ),
        }
        return self.out.relative(self.out.write_json(f"{name}.json", document))
