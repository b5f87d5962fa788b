"""The Edit view: an artist's edit learned on one clip and propagated to others (Ikemoto
et al. 2009, the commands ``rigmap edits learn``, ``apply --model`` and ``fix``; issue #43,
item 3).

Pick a BVH clip under the served folder and its frames (``START:STOP``, the file's frames
as ``rigmap edits learn --frames`` takes them), drag a hand, a foot or the head at a frame
with its gizmo; ticked joints are pinned. The drag is held by §5's IK over the whole range
(:func:`rigmap.studio.edit_clips.hold_edit`: the library keys an edit at one frame with a
linear blend, an example pair must hold it over its frames). "Learn edit" writes the
edited clip (the whole file, the range replaced: §3's pair, same frames) and learns with
:func:`rigmap.edits.artist.learn_folder`, the call of ``rigmap edits learn``; "Apply" is
:func:`~rigmap.edits.artist.apply_folder` (``rigmap edits apply --model``), its result
drawn beside the source over the clip it edited, playable; "Hand in fix" holds a drag on
that result over a few frames, writes them and runs :func:`rigmap.edits.fixes.fix_folder`
(``rigmap edits fix``: the refit), then applies again. Long calls run on one worker
thread (buttons disabled meanwhile, progress in the page). Files are read only through
:class:`~rigmap.studio.served_folder.ServedFolder` and written only under the
:class:`~rigmap.studio.writes.OutputFolder`.
"""

from __future__ import annotations

import json
import queue
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np

from rigmap.animation.bvh_write import write_bvh
from rigmap.edits.artist import apply_folder, learn_folder, read_track
from rigmap.edits.authoring import AuthoringError
from rigmap.edits.fixes import fix_folder
from rigmap.edits.skeleton_mode import track_motion
from rigmap.errors import RigmapError
from rigmap.studio.camera import CameraPose, aim_every_page, front_camera
from rigmap.studio.edit_clips import (
    DISPLAY_HEIGHT_M,
    GIZMO_ROLES,
    AppliedClip,
    EditViewError,
    FixReport,
    LearnedEdit,
    OpenedClip,
    applied_line,
    bvh_clips,
    file_motion,
    fixed_line,
    frames_of,
    heading_joints,
    hold_edit,
    learned_line,
    open_clip,
    pose_edit,
    rms,
    to_heading_frame,
    vector,
)
from rigmap.studio.playback import FrameClock, PlaysFrames
from rigmap.studio.scene import GIZMO_SHARE, SkeletonDrawing, from_scene
from rigmap.studio.served_folder import ServedFolder
from rigmap.studio.writes import OutputFolder

SCENE = "/edit"
PICK = "(pick a BVH clip)"
NONE_FOUND = "(no .bvh file under the folder)"
ROLE_LABELS = {
    "hand_l": "left hand",
    "hand_r": "right hand",
    "foot_l": "left foot",
    "foot_r": "right foot",
    "head": "head",
}
PINNED_ROLES = ("foot_l", "foot_r")  # ours: a drag keeps the feet planted unless unticked
#: the propagated clip's place, this far right of the source (m; ours)
RESULT_GAP_M = 1.2
#: a fix spans this many frames either side of the frame dragged, unless typed (ours)
FIX_HALF = 12
#: the fix's suggestions: ``rigmap edits fix``'s defaults (--suggest, --segment)
SUGGEST, SEGMENT = 3, 12
GHOST_COLOR = (170, 170, 170)  # the unedited clip
EDIT_COLOR = (40, 90, 200)
RESULT_COLOR = (220, 110, 20)


class EditView(PlaysFrames):
    """The view. ``served``: where clips are read; ``out``: where everything is written;
    ``settings``: the edit model's settings (``conf/edits/default.yaml``'s ``edits`` node
    as a dict: ``residual``, ``weights``, ``max_iterations``, ``input_scale``), as
    :func:`rigmap.app.edits.load_settings` reads them; ``glitch``: ``repair`` or ``refuse``
    (``--glitch``)."""

    name = "Edit"

    def __init__(
        self,
        served: ServedFolder,
        out: OutputFolder,
        settings: Mapping,
        *,
        glitch: str = "repair",
    ):
        missing = sorted({"residual", "weights", "max_iterations"} - set(settings))
        if missing:
            raise ValueError(f"the edit settings lack {missing} (conf/edits/default.yaml's)")
        if glitch not in ("repair", "refuse"):
            raise ValueError(f"glitch must be repair or refuse, got {glitch!r}")
        self.served, self.out, self.glitch = served, out, glitch
        self.settings = dict(settings)
        self.source: OpenedClip | None = None
        self.frame = 0  # the source's clip frame shown
        self.drags: dict[str, np.ndarray] = {}  # joint -> heading-frame drag (file units)
        self.fix_drags: dict[str, np.ndarray] = {}  # the same, on the propagated clip
        self.learned: LearnedEdit | None = None
        self.result: AppliedClip | None = None
        self.result_frame = 0
        self.fix: FixReport | None = None
        self.camera: CameraPose | None = None
        self.gizmo_scale = GIZMO_SHARE * DISPLAY_HEIGHT_M
        self._gizmos: dict[str, object] = {}
        self._fix_gizmos: dict[str, object] = {}
        self._anchors: dict[str, np.ndarray] = {}
        self._fix_anchors: dict[str, np.ndarray] = {}
        self.drawings: dict[str, SkeletonDrawing] = {}
        self._labels: dict[str, object] = {}
        self._visible = True
        self._lock = threading.RLock()
        self._preview_lock = threading.Lock()
        self._seq = {"source": 0, "result": 0}
        self._jobs: queue.Queue = queue.Queue()
        self._busy = False
        self._idle = threading.Event()
        self._idle.set()
        self._worker = threading.Thread(target=self._work_loop, name="studio-edit", daemon=True)
        self._clock = FrameClock("studio-edit-play")

    # ------------------------------------------------------------------ page
    def build(self, server, gui) -> None:
        self.server = server
        options = self._clip_options()
        self.clip_menu = gui.add_dropdown("Source clip", options=options)
        self.clip_text = gui.add_text(
            "Source file", "", hint="a .bvh file, relative to the served folder"
        )
        self.frames_text = gui.add_text(
            "Frames", "", hint="START:STOP, the file's frames from 0 (STOP excluded), or all"
        )
        self.open_button = gui.add_button("Open clip")
        self.message = gui.add_markdown("")
        self.frame_slider = gui.add_slider(
            "Frame", min=0, max=1, step=1, initial_value=0, disabled=True
        )
        self.pin_boxes = {
            role: gui.add_checkbox(f"Pin {ROLE_LABELS[role]}", role in PINNED_ROLES)
            for role in GIZMO_ROLES
        }
        self.drag_line = gui.add_markdown("")
        self.reset_button = gui.add_button("Reset drags", disabled=True)
        self.learn_button = gui.add_button("Learn edit", disabled=True)
        self.status = gui.add_markdown("Pick a clip, drag a hand, a foot or the head, learn.")
        self.apply_menu = gui.add_dropdown("Apply to", options=options)
        self.apply_text = gui.add_text(
            "Apply to file", "", hint="a .bvh file of the same skeleton, relative to the folder"
        )
        self.apply_button = gui.add_button("Apply", disabled=True)
        self.result_slider = gui.add_slider(
            "Result frame", min=0, max=1, step=1, initial_value=0, disabled=True
        )
        self.play_button = gui.add_button("Play", disabled=True)
        self.fix_text = gui.add_text(
            "Fix frames",
            "",
            hint=f"START:STOP of the applied clip's file; empty: {FIX_HALF} frames either "
            "side of the result frame",
        )
        self.fix_button = gui.add_button("Hand in fix", disabled=True)
        self.result_status = gui.add_markdown("")
        self._connect()
        self._worker.start()
        self._clock.start()

    def _connect(self) -> None:
        self.clip_menu.on_update(lambda _event: self._clip_picked())
        self.open_button.on_click(
            lambda _event: self.open(self.clip_text.value, self.frames_text.value)
        )
        self.frame_slider.on_update(lambda _event: self._slid())
        for box in self.pin_boxes.values():
            box.on_update(lambda _event: self._pins_changed())
        self.reset_button.on_click(lambda _event: self.reset_drags())
        self.learn_button.on_click(lambda _event: self.submit("Learning the edit", self.learn))
        self.apply_menu.on_update(lambda _event: self._apply_picked())
        self.apply_button.on_click(lambda _event: self._apply_clicked())
        self.result_slider.on_update(lambda event: self._result_slid(event))
        self.play_button.on_click(lambda _event: self.toggle())
        self.fix_button.on_click(lambda _event: self.submit("Handing in the fix", self.hand_in_fix))

    def show(self, visible: bool) -> None:
        self._visible = visible
        if not visible:
            self.pause()
        with self._lock:
            for handle in self._handles():
                handle.visible = visible
        if visible and self.camera is not None:
            aim_every_page(self.camera, self.server)

    def close(self) -> None:
        self._clock.close()
        self._jobs.put(None)

    # ------------------------------------------------------------------ clips
    def _clip_options(self) -> list[str]:
        found = bvh_clips(self.served)
        return [PICK, *found] if found else [NONE_FOUND]

    def _clip_picked(self) -> None:
        if self.clip_menu.value not in (PICK, NONE_FOUND):
            self.clip_text.value = self.clip_menu.value
            self.open(self.clip_menu.value, self.frames_text.value)

    def _apply_picked(self) -> None:
        if self.apply_menu.value not in (PICK, NONE_FOUND):
            self.apply_text.value = self.apply_menu.value

    def _bvh(self, requested: str) -> tuple[Path, str]:
        path = self.served.resolve(requested, kind="file")
        name = self.served.relative(path)
        if path.suffix.lower() != ".bvh":
            raise EditViewError(f"{name!r}: not a .bvh file")
        return path, name

    def open(self, requested: str, frames_text: str = "") -> OpenedClip | None:
        """Open the clip ``requested`` (relative to the served folder), frames
        ``frames_text``, at its first frame; a refused or unreadable one is shown in the page
        and returned None."""
        if self._busy:
            self.message.content = "**Busy:** wait for the job running to finish"
            return None
        self.pause()
        try:
            path, name = self._bvh(requested)
            frames = frames_of(frames_text)
            self.message.content = f"Opening {name}…"
            opened = open_clip(path, name, frames, self.glitch)
        except (RigmapError, ValueError, OSError) as error:
            self.message.content = f"**Not opened:** {error}"
            return None
        with self._lock:
            self._clear(self.drawings, self._gizmos, self._fix_gizmos, self._labels)
            self.source, self.frame, self.drags, self.fix_drags = opened, 0, {}, {}
            self.learned, self.result, self.fix = None, None, None
            self._draw_source(opened)
        self._frame_camera(opened)
        first = opened.clip.start
        self.frame_slider.max = first + opened.n_frames - 1
        self.frame_slider.min = first
        self.frame_slider.value = first
        self.frame_slider.disabled = False
        self.message.content = (
            f"**{name}**: frames {first}:{first + opened.n_frames} of the file, "
            f"{opened.n_frames} at {opened.clip.track.fps:g} fps · grey: the clip, blue: "
            "edited" + "".join(f" · {note}" for note in opened.clip.notes)
        )
        self.status.content = "Drag a gizmo (pinned joints are held), then Learn edit."
        self.result_status.content = ""
        self.show_frame(0)
        self._refresh_buttons()
        return opened

    # ------------------------------------------------------------------ scene
    @staticmethod
    def _scene_points(joints: np.ndarray, scale: float, slot: int = 0) -> np.ndarray:
        return np.asarray(joints) * scale + np.array([slot * RESULT_GAP_M, 0.0, 0.0])

    def _handles(self) -> list:
        return [
            *self.drawings.values(),
            *self._gizmos.values(),
            *self._fix_gizmos.values(),
            *self._labels.values(),
        ]

    @staticmethod
    def _clear(*groups: dict) -> None:
        for group in groups:
            for handle in group.values():
                handle.remove()
            group.clear()

    def _draw_source(self, opened: OpenedClip) -> None:
        first = self._scene_points(opened.joints[0], opened.scale)
        colors = (("source", GHOST_COLOR), ("edit", EDIT_COLOR))
        self._gizmos.update(
            self._draw_pair(opened, first, "source", colors, "edited (blue) over the clip")
        )

    def _draw_pair(self, opened: OpenedClip, points, place: str, colors, caption: str) -> dict:
        """Two skeletons of ``opened`` at ``points`` (scene units) under ``place`` (the clip
        and its edit: ``colors`` names and colours them), its gizmos and its label; returns
        the gizmos."""
        for key, color in colors:
            self.drawings[key] = SkeletonDrawing(
                self.server.scene,
                f"{SCENE}/{place}/{key}",
                opened.skeleton,
                from_scene(points),
                color=color,
            )
            self.drawings[key].visible = self._visible
        gizmos = self._add_gizmos(opened, points, place)
        self._labels[place] = self._label(place, caption, points)
        return gizmos

    def _add_gizmos(self, opened: OpenedClip, points: np.ndarray, kind: str) -> dict:
        gizmos = {}
        for joint in opened.gizmos.values():
            gizmo = self.server.scene.add_transform_controls(
                f"{SCENE}/{kind}/gizmos/{joint}",
                scale=self.gizmo_scale,
                disable_rotations=True,
                position=tuple(points[opened.joint(joint)]),
            )
            gizmo.on_update(lambda event, joint=joint: self._gizmo_moved(kind, joint, event))
            gizmo.visible = self._visible
            gizmos[joint] = gizmo
        return gizmos

    def _label(self, key: str, text: str, points: np.ndarray):
        above = (float(points[:, 0].mean()), float(points[:, 1].max()) + 0.15, 0.0)
        label = self.server.scene.add_label(
            f"{SCENE}/labels/{key}", text, position=above, anchor="bottom-center"
        )
        label.visible = self._visible
        return label

    def _frame_camera(self, opened: OpenedClip) -> None:
        """Every page's camera (and a new page's) in front of the source and the place of
        the propagated clip beside it, for the whole clip (it does not move afterwards)."""
        points = self._scene_points(opened.joints.reshape(-1, 3), opened.scale)
        both = np.concatenate([points, points + np.array([RESULT_GAP_M, 0.0, 0.0])])
        self.camera = front_camera(both)
        aim_every_page(self.camera, self.server)

    def gizmo(self, joint: str):
        """The source's gizmo of ``joint`` (a joint name, or a role such as ``hand_r``)."""
        joint = self.source.gizmos.get(joint, joint)
        return self._gizmos[joint]

    def fix_gizmo(self, joint: str):
        """The propagated clip's gizmo of ``joint`` (a name or a role)."""
        joint = self.result.input.gizmos.get(joint, joint)
        return self._fix_gizmos[joint]

    # ------------------------------------------------------------------ frames and drags
    def _slid(self) -> None:
        if self.source is not None:
            self.show_frame(int(self.frame_slider.value) - self.source.clip.start)

    def show_frame(self, frame: int) -> None:
        """The source at its clip frame ``frame``, the gizmos at its joints plus the drags."""
        with self._lock:
            source = self.source
            if source is None:
                return
            self.frame = int(np.clip(frame, 0, source.n_frames - 1))
            points = self._scene_points(source.joints[self.frame], source.scale)
            self.drawings["source"].update(from_scene(points))
            self._anchors = {j: points[source.joint(j)] for j in self._gizmos}
            self._place(self._gizmos, self._anchors, self.drags, source.scale)
        self._preview("source")

    @staticmethod
    def _place(gizmos: dict, anchors: dict, drags: dict, scale: float) -> None:
        for joint, gizmo in gizmos.items():
            gizmo.position = tuple(anchors[joint] + scale * drags.get(joint, np.zeros(3)))

    def _gizmo_moved(self, kind: str, joint: str, event) -> None:
        with self._lock:
            source = kind == "source"
            anchors = self._anchors if source else self._fix_anchors
            gizmos = self._gizmos if source else self._fix_gizmos
            opened = self.source if source else self._result_input()
            if opened is None or gizmos.get(joint) is not event.target:
                return  # a late update of a gizmo removed since (another clip opened)
            drag = (np.asarray(event.target.position) - anchors[joint]) / opened.scale
            (self.drags if kind == "source" else self.fix_drags)[joint] = drag
        self._preview(kind)

    def drag(self, joint: str, offset, *, on: str = "source") -> None:
        """Drag ``joint`` (a name or a role) by ``offset`` (heading frame: x left, y up, z
        forward; file units) on the source or, ``on="result"``, on the propagated clip, as
        moving its gizmo in the page does."""
        if on not in ("source", "result"):
            raise ValueError(f"on must be source or result, got {on!r}")
        with self._lock:
            fix = on == "result"
            opened = self._result_input() if fix else self.source
            if opened is None:
                raise EditViewError("apply the edit first" if fix else "open a clip first")
            joint = opened.gizmos.get(joint, joint)
            if joint not in opened.gizmos.values():
                raise EditViewError(f"{joint!r}: no gizmo; these have: {list(opened.gizmos)}")
            drags = self.fix_drags if fix else self.drags
            drags[joint] = np.asarray(offset, dtype=np.float64).reshape(3)
            gizmos, anchors = (
                (self._fix_gizmos, self._fix_anchors) if fix else (self._gizmos, self._anchors)
            )
            self._place(gizmos, anchors, drags, opened.scale)
        self._preview(on)

    def reset_drags(self) -> None:
        with self._lock:
            self.drags, self.fix_drags = {}, {}
            if self.source is not None:
                self._place(self._gizmos, self._anchors, {}, self.source.scale)
            if self.result is not None:
                self._place(self._fix_gizmos, self._fix_anchors, {}, self.result.input.scale)
        self._preview("source")
        self._preview("result")

    def _pins_changed(self) -> None:
        self._preview("source")
        self._preview("result")

    def pins(self, opened: OpenedClip) -> tuple[str, ...]:
        """The joints ticked to be pinned."""
        return tuple(
            opened.gizmos[role]
            for role, box in self.pin_boxes.items()
            if box.value and role in opened.gizmos
        )

    @staticmethod
    def _moved(drags: dict) -> dict[str, np.ndarray]:
        return {j: d.copy() for j, d in drags.items() if np.linalg.norm(d) > 0}

    def _preview_inputs(self, kind: str):
        """What a preview of ``kind`` needs, read under the lock (None: nothing to show)."""
        if kind == "source":
            if self.source is None:
                return None
            opened, track, frame = self.source, self.source.clip.track, self.frame
            return opened, track, frame, self.source.joints[frame], self._moved(self.drags), 0
        if self.result is None:
            return None
        opened, frame = self.result.input, self.result_frame
        track, joints = self.result.track, self.result.joints[frame]
        return opened, track, frame, joints, self._moved(self.fix_drags), 1

    def _preview(self, kind: str) -> None:
        """Pose the edited skeleton (``source``) or the fixed one (``result``) at its frame
        with the IK; the newest drag wins (a drag sends events faster than the IK)."""
        with self._lock:
            self._seq[kind] += 1
            seq = self._seq[kind]
        with self._preview_lock:
            with self._lock:
                if seq != self._seq[kind]:
                    return
                inputs = self._preview_inputs(kind)
                if inputs is None:
                    return
                opened, track, frame, joints, drags, slot = inputs
                pins = self.pins(opened)
            started, line = time.perf_counter(), ""
            if drags:
                try:
                    _, solved = pose_edit(track, opened.skeleton, frame, drags, pins)
                    joints = to_heading_frame(track, frame, solved)
                    line = f"IK {1e3 * (time.perf_counter() - started):.0f} ms"
                except AuthoringError as error:
                    line = f"**IK:** {error}; drag less far"
            with self._lock:
                still = opened is (self.source if kind == "source" else self._result_input())
                if still:
                    key = "edit" if kind == "source" else "result"
                    points = self._scene_points(joints, opened.scale, slot)
                    self.drawings[key].update(from_scene(points))
                    self.drag_line.content = self._drag_text(kind, opened, frame, drags, line)
        self.server.flush()

    def _result_input(self):
        return None if self.result is None else self.result.input

    @staticmethod
    def _drag_text(kind, opened: OpenedClip, frame: int, drags: dict, ik: str) -> str:
        where = "source" if kind == "source" else "propagated clip"
        moved = " · ".join(f"{j} {vector(d)}" for j, d in drags.items()) or "no drag"
        return f"{where}, frame {opened.clip.start + frame}: {moved} · {ik}".rstrip(" ·")

    # ------------------------------------------------------------------ jobs
    def submit(self, label: str, job: Callable) -> bool:
        """Run ``job(progress)`` on the worker thread, the buttons disabled meanwhile; its
        error is shown in the page. False when another job runs."""
        with self._lock:
            if self._busy:
                self.message.content = "**Busy:** one job at a time"
                return False
            self._busy = True
            self._idle.clear()
        self._refresh_buttons()
        self.message.content = f"{label}…"
        self._jobs.put((label, job))
        return True

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Wait for the job running (if any) to finish; False on timeout."""
        return self._idle.wait(timeout)

    def _work_loop(self) -> None:
        while True:
            item = self._jobs.get()
            if item is None:
                return
            label, job = item
            started = time.perf_counter()

            def progress(done, total, label=label):
                self.message.content = f"{label}: the IK on {done} of {total} frames…"

            try:
                job(progress)
                self.message.content = f"{label}: done in {time.perf_counter() - started:.1f} s"
            except (RigmapError, ValueError, OSError) as error:
                self.message.content = f"**{label}: not done.** {error}"
            except Exception as error:  # shown in the page; the studio keeps serving
                self.message.content = f"**{label} failed:** {type(error).__name__}: {error}"
            finally:
                with self._lock:
                    self._busy = False
                self._refresh_buttons()
                self._idle.set()

    def _refresh_buttons(self) -> None:
        busy, result = self._busy, self.result
        self.open_button.disabled = busy
        self.learn_button.disabled = busy or self.source is None
        self.reset_button.disabled = self.source is None
        self.apply_button.disabled = busy or self.learned is None
        self.fix_button.disabled = busy or result is None or not result.same_frames
        self.play_button.disabled = result is None
        self.result_slider.disabled = result is None

    def _apply_clicked(self) -> None:
        requested = self.apply_text.value
        self.submit("Applying the edit", lambda _progress: self.apply(requested))

    def _new_folder(self, stem: str) -> Path:
        """``edits/<clip>_<n>/`` under the output folder, a new one per edit learned."""
        return self.out.new_folder(f"edits/{stem}")

    # ------------------------------------------------------------------ learn, apply, fix
    def learn(self, progress=None) -> LearnedEdit:
        """Hold the drags over the clip's frames, write the edited clip and learn the edit
        from the pair (``rigmap edits learn --source --edited --frames``'s call)."""
        with self._lock:
            source, drags = self.source, self._moved(self.drags)
            pins = () if source is None else self.pins(source)
        if source is None:
            raise EditViewError("open a clip first")
        if not drags:
            raise EditViewError("drag a hand, a foot or the head first: there is no edit")
        track, failed = hold_edit(
            source.clip.track, source.skeleton, range(source.n_frames), drags, pins, progress
        )
        folder = self._new_folder(Path(source.name).stem)
        edited = write_bvh(file_motion(source.raw, source.clip, track), folder / "edited.bvh")
        model = self.out.path(f"{self.out.relative(folder)}/model")
        learn_folder([(source.path, edited, source.frames)], model, self.settings, self.glitch)
        summary = json.loads((model / "learned.json").read_text())
        learned = LearnedEdit(folder, model, edited, source, drags, summary, failed)
        with self._lock:
            if self.source is source:
                self._clear(self._fix_gizmos)
                for key in ("input", "result"):
                    self._drop(self.drawings, key)
                self._drop(self._labels, "result")
                self.learned, self.result, self.fix, self.fix_drags = learned, None, None, {}
        self.status.content = learned_line(learned, self.out)
        self.result_status.content = ""
        self._refresh_buttons()
        return learned

    @staticmethod
    def _drop(group: dict, key: str) -> None:
        handle = group.pop(key, None)
        if handle is not None:
            handle.remove()

    def apply(self, requested: str) -> AppliedClip:
        """Propagate the learned edit to the clip ``requested`` (relative to the served
        folder; ``rigmap edits apply --model``'s call) and show it beside the source."""
        learned = self.learned
        if learned is None:
            raise EditViewError("learn an edit first (Learn edit)")
        path, name = self._bvh(requested)
        applied = self._apply(learned, open_clip(path, name, None, self.glitch))
        self._show_result(applied, 0)
        self.result_status.content = applied_line(applied, learned.drags, self.out)
        return applied

    def _apply(self, learned: LearnedEdit, target: OpenedClip) -> AppliedClip:
        out = learned.folder / "applied"
        _, summary = apply_folder(learned.model, target.path, out, None, self.glitch)
        (row,) = summary["clips"]
        track = read_track(out / f"{target.path.stem}.npz")
        joints = heading_joints(track, target.skeleton)
        return AppliedClip(target, Path(row["bvh"]), track, joints, row)

    def _show_result(self, applied: AppliedClip, frame: int) -> None:
        with self._lock:
            self._clear(self._fix_gizmos)
            for key in ("input", "result"):
                self._drop(self.drawings, key)
            self._drop(self._labels, "result")
            self.result, self.fix_drags = applied, {}
            opened = applied.input
            points = self._scene_points(applied.joints[0], opened.scale, 1)
            colors = (("input", GHOST_COLOR), ("result", RESULT_COLOR))
            self._fix_gizmos.update(
                self._draw_pair(opened, points, "result", colors, "propagated (orange) over it")
            )
        first = opened.clip.start if applied.same_frames else 0
        self.result_slider.max = first + len(applied.joints) - 1
        self.result_slider.min = first
        self.result_slider.value = first + frame
        self.show_result_frame(frame)
        self._refresh_buttons()

    def _result_slid(self, event) -> None:
        result = self.result
        if result is None:
            return
        first = result.input.clip.start if result.same_frames else 0
        if event.client_id is not None and self._clock.playing:  # a scrub during playback
            self._clock.rewind(int(self.result_slider.value) - first)
        self.show_result_frame(int(self.result_slider.value) - first)

    def show_result_frame(self, frame: int) -> None:
        """The propagated clip (and the clip it edited, grey) at its frame ``frame``."""
        with self._lock:
            result = self.result
            if result is None:
                return
            opened = result.input
            self.result_frame = int(np.clip(frame, 0, len(result.joints) - 1))
            ghost = opened.joints[min(self.result_frame, opened.n_frames - 1)]
            self.drawings["input"].update(from_scene(self._scene_points(ghost, opened.scale, 1)))
            points = self._scene_points(result.joints[self.result_frame], opened.scale, 1)
            self._fix_anchors = {j: points[opened.joint(j)] for j in self._fix_gizmos}
            self._place(self._fix_gizmos, self._fix_anchors, self.fix_drags, opened.scale)
        self._preview("result")

    def _fix_range(self, applied: AppliedClip, frame: int) -> tuple[int, int]:
        """The fix's clip frames: typed (the file's frames) or around ``frame``."""
        n, first = len(applied.joints), applied.input.clip.start
        typed = frames_of(self.fix_text.value)
        if typed is None:
            return max(0, frame - FIX_HALF), min(n, frame + FIX_HALF + 1)
        start, stop = typed[0] - first, typed[1] - first
        if not 0 <= start < stop <= n:
            raise EditViewError(
                f"Fix frames {self.fix_text.value!r}: outside the frames of "
                f"{applied.input.name}, {first}:{first + n}"
            )
        return start, stop

    def hand_in_fix(self, progress=None) -> FixReport:
        """Hold the drags on the propagated clip over the fix's frames, write those frames,
        refit (``rigmap edits fix``'s call) and apply the edit again."""
        with self._lock:
            learned, applied, frame = self.learned, self.result, self.result_frame
            drags = self._moved(self.fix_drags)
        if learned is None or applied is None:
            raise EditViewError("apply the edit to a clip first")
        if not applied.same_frames:
            raise EditViewError(
                f"{applied.input.name}: the propagated clip was resampled (a timing edit); "
                "its frames are not the file's, so a fix cannot name them"
            )
        if not drags:
            raise EditViewError("drag a gizmo on the propagated clip first: there is no fix")
        target = applied.input
        start, stop = self._fix_range(applied, frame)
        fixed, failed = hold_edit(
            applied.track, target.skeleton, range(start, stop), drags, self.pins(target), progress
        )
        frames = (target.clip.start + start, target.clip.start + stop)
        rows = track_motion(fixed, target.clip.motion).values[start:stop]
        stem = f"{target.path.stem}_{frames[0]}_{frames[1]}"
        name = f"{self.out.relative(learned.folder)}/handed_in/{stem}.bvh"
        handed = write_bvh(replace(target.clip.motion, values=rows), self.out.path(name))
        wanted = heading_joints(fixed, target.skeleton)[start:stop]
        before = rms(applied.joints[start:stop], wanted)
        picks, notes = fix_folder(
            learned.model, target.path, handed, frames, self.settings, SUGGEST, SEGMENT
        )
        learned = replace(learned, summary=json.loads((learned.model / "learned.json").read_text()))
        again = self._apply(learned, target)
        after = rms(again.joints[start:stop], wanted) if again.same_frames else None
        report = FixReport(
            target.name, frames, handed, learned.summary, before, after, picks, notes, len(failed)
        )
        with self._lock:
            self.learned, self.fix = learned, report
        self._show_result(again, frame)
        self.result_status.content = fixed_line(report, self.out)
        return report

    # ------------------------------------------------------------------ playback
    def play(self) -> None:
        """Play the propagated clip from the frame shown, at its frame rate, looping."""
        result = self.result
        if result is None:
            return
        offset = result.input.clip.start if result.same_frames else 0

        def tick(frame: int) -> None:
            if frame != self.result_frame and result is self.result:
                self.result_slider.value = offset + frame

        self._clock.play(self.result_frame, len(result.joints), result.track.fps, tick)
        self.play_button.label = "Pause"

    def pause(self) -> None:
        if self._clock.pause():
            self.play_button.label = "Play"
