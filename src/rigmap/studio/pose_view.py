"""The Pose view: drag a rig's effectors; the partial-input mapping and refinement answer
(Holden et al. 2017, Figs 5, 6, 10: full-body IK, feet only, FaceIK).

Each effector is a translation gizmo. A drag sends a stream of positions; the view keeps
only the newest targets and one worker thread poses them (a pose takes ~10-30 ms, drags
arrive faster), so the rig follows the hand instead of a growing queue. The skeleton (and
a mesh rig's surface) shows the pose reached; the gizmos stay where the user put them.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from rigmap.studio.camera import CameraPose, aim_every_page, front_camera
from rigmap.studio.scene import (
    SkeletonDrawing,
    add_surface,
    from_scene,
    to_scene,
    world_pose,
)
from rigmap.studio.writes import OutputFolder

SCENE = "/pose"
#: a gizmo's size as a share of the character's height (ours: grabbable, not in the way)
GIZMO_SHARE = 0.085
#: a joint's dot, as a share of the character's height (ours)
JOINT_SHARE = 0.011
#: the controls listed in the page: the most moved from rest (the export has every one); ours
LISTED_CONTROLS = 16


@dataclass
class PoseSession:
    """A rig ready to be posed: ``pose(targets (K, 3) cm) -> (controls (C,), distance cm)``
    for the ``effectors`` joints; ``reset()`` starts a new drag; ``rest`` the first pose."""

    rig: object
    effectors: tuple[str, ...]
    pose: Callable[[np.ndarray], tuple[np.ndarray, float]]
    reset: Callable[[], None]
    rest: np.ndarray
    description: str = ""


@dataclass
class PoseRecord:
    """What the page last showed: the pose's count, controls, distance and timings."""

    count: int = 0
    controls: np.ndarray | None = None
    distance_cm: float = float("nan")
    pose_ms: list[float] = field(default_factory=list)


class PoseView:
    """The view; ``sessions`` maps a rig name to a factory (called when it is picked)."""

    name = "Pose"

    def __init__(self, sessions: Mapping[str, Callable[[], PoseSession]], out: OutputFolder):
        if not sessions:
            raise ValueError("the Pose view needs at least one rig")
        self.factories = dict(sessions)
        self.out = out
        self.session: PoseSession | None = None
        self.record = PoseRecord()
        self._targets: np.ndarray | None = None
        self._wake = threading.Condition()
        self._stop = False
        self._new_drag = False
        self._drawing = None
        self._mesh = None
        self._gizmos = []
        self.camera: CameraPose | None = None
        self.gizmo_scale = 0.1
        self._worker = threading.Thread(target=self._pose_loop, name="studio-pose", daemon=True)

    # ------------------------------------------------------------------ page
    def build(self, server, gui) -> None:
        self.server = server
        self.rig_menu = gui.add_dropdown("Rig", options=list(self.factories))
        self.status = gui.add_markdown("Pick a rig.")
        self.reset_button = gui.add_button("Reset pose")
        self.export_button = gui.add_button("Export pose (JSON)")
        self.listing = gui.add_markdown("")
        self.rig_menu.on_update(lambda _event: self.load(self.rig_menu.value))
        self.reset_button.on_click(lambda _event: self.load(self.rig_menu.value))
        self.export_button.on_click(lambda _event: self.export())
        self._worker.start()
        self.load(self.rig_menu.value)

    def show(self, visible: bool) -> None:
        for handle in (self._drawing, self._mesh, *self._gizmos):
            if handle is not None:
                handle.visible = visible
        if visible and self.camera is not None:  # another view may have moved it
            aim_every_page(self.camera, self.server)

    def close(self) -> None:
        with self._wake:
            self._stop = True
            self._wake.notify()

    # ------------------------------------------------------------------ rig
    def load(self, rig_name: str) -> None:
        """Build (or rebuild) the scene for ``rig_name`` at its rest pose."""
        self.status.content = f"Loading {rig_name}: fitting or reading its effector mapping…"
        try:
            session = self.factories[rig_name]()
        except Exception as error:  # shown in the page; the studio keeps serving
            self.status.content = f"**{rig_name}**: {error}"
            return
        with self._wake:
            self._targets = None
            self._clear()
            self.session = session
            self.record = PoseRecord(controls=session.rest.copy())
            shown = self._draw(session, *world_pose(session.rig, session.rest))
        self.frame(shown)
        self._show_pose(session.rest, 0.0, 0.0)
        self._list_controls()

    def frame(self, points) -> None:
        """Every page's camera (and a new page's) in front of the character."""
        self.camera = front_camera(points)
        aim_every_page(self.camera, self.server)

    def _clear(self) -> None:
        for handle in (self._drawing, self._mesh, *self._gizmos):
            if handle is not None:
                handle.remove()
        self._drawing, self._mesh, self._gizmos = None, None, []

    def _draw(self, session: PoseSession, joints: np.ndarray, surface) -> np.ndarray:
        """The skeleton, a mesh rig's ``surface`` (None: none) and the gizmos; returns the
        points to frame (scene units: the surface's if there is one, else the joints')."""
        scene, rig = self.server.scene, session.rig
        shown = to_scene(joints)
        if surface is not None:
            shown = to_scene(surface)
            self._mesh = add_surface(scene, f"{SCENE}/mesh", shown, rig.faces, (225, 190, 170))
        height = float(np.ptp(shown[:, 1]) or np.ptp(shown, axis=0).max())
        self.gizmo_scale = GIZMO_SHARE * height
        self._drawing = SkeletonDrawing(
            scene, f"{SCENE}/skeleton", rig, joints, size=JOINT_SHARE * height
        )
        names = list(rig.joint_names)
        for joint in session.effectors:
            gizmo = scene.add_transform_controls(
                f"{SCENE}/effectors/{joint}",
                scale=self.gizmo_scale,
                disable_rotations=True,
                depth_test=False,  # drawn over a mesh rig's surface, so always grabbable
                position=tuple(to_scene(joints[names.index(joint)])),
            )
            gizmo.on_update(self._gizmo_event)
            self._gizmos.append(gizmo)
        return shown

    def gizmo(self, joint: str):
        """The gizmo of effector ``joint`` of the current rig."""
        return self._gizmos[self.session.effectors.index(joint)]

    # ------------------------------------------------------------------ drags
    def _gizmo_event(self, event) -> None:
        """A gizmo's drag: ``start`` begins a new drag, every phase moves the targets, ``end``
        lists the controls reached."""
        phase = getattr(event, "phase", "update")
        if phase == "start":
            with self._wake:  # the worker resets, between poses: never under a running one
                self._new_drag = True
        self._targets_moved()
        if phase == "end":
            self._list_controls()

    def _targets_moved(self) -> None:
        targets = from_scene(np.array([g.position for g in self._gizmos]))
        with self._wake:
            self._targets = targets
            self._wake.notify()

    def _pose_loop(self) -> None:
        while True:
            with self._wake:
                while self._targets is None and not self._stop:
                    self._wake.wait()
                if self._stop:
                    return
                targets, self._targets = self._targets, None
                session, new_drag, self._new_drag = self.session, self._new_drag, False
            started = time.perf_counter()
            try:
                if new_drag:
                    session.reset()
                controls, distance = session.pose(targets)
            except Exception as error:  # shown in the page; the next drag tries again
                self.status.content = f"**{session.rig.name}**: posing failed: {error}"
                continue
            seconds = time.perf_counter() - started
            if session is self.session:
                self._show_pose(controls, distance, seconds)

    def _show_pose(self, controls: np.ndarray, distance: float, seconds: float) -> None:
        session = self.session
        rig = session.rig
        joints, surface = world_pose(rig, controls)
        self._drawing.update(joints)
        if self._mesh is not None and surface is not None:
            self._mesh.vertices = to_scene(surface)
        record = self.record
        record.count += 1
        record.controls = np.asarray(controls, dtype=np.float64)
        record.distance_cm = float(distance)
        record.pose_ms.append(1e3 * seconds)
        self.status.content = (
            f"**{rig.name}** · {len(session.effectors)} effectors · pose {record.count} · "
            f"{record.distance_cm:.2f} cm from the targets · {1e3 * seconds:.0f} ms"
        )
        self.server.flush()  # now, not at the end of viser's 1/60 s window

    def _list_controls(self) -> None:
        """The controls table, when a drag ends (re-laying it out every pose costs the
        page a frame's time)."""
        session, record = self.session, self.record
        if session is not None and record.controls is not None:
            self.listing.content = self._listing(session.rig, record.controls, session.rest)

    @staticmethod
    def _listing(rig, controls: np.ndarray, rest: np.ndarray) -> str:
        used = np.asarray(rig.controls.used_indices)
        moved = np.abs(controls[used] - rest[used])
        order = used[np.argsort(-moved, kind="stable")][:LISTED_CONTROLS]
        rows = [f"| {rig.control_names[i]} | {controls[i]:.3f} |" for i in order]
        head = f"{len(used)} used controls; the {len(rows)} most moved from rest:"
        return "\n".join([head, "", "| control | value |", "|---|---|", *rows])

    # ------------------------------------------------------------------ export
    def export(self) -> None:
        session, record = self.session, self.record
        if session is None or record.controls is None:
            return
        rig = session.rig
        used = rig.controls.used_indices
        targets = from_scene(np.array([g.position for g in self._gizmos]))
        document = {
            "rig": rig.name,
            "effectors": {j: t.tolist() for j, t in zip(session.effectors, targets, strict=True)},
            "target_distance_rms_cm": record.distance_cm,
            "used_controls": dict(
                zip(rig.used_controls, record.controls[used].tolist(), strict=True)
            ),
        }
        path = self.out.write_json(f"pose/{rig.name}-{record.count}.json", document)
        self.status.content += f"\n\nExported {self.out.relative(path)}"
