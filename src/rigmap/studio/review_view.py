"""The Review view: a ``rigmap map`` output folder played back (issue #43, item 2).

The rig at the mapped controls (``controls.parquet`` through ``rig.pose``) and the
retargeted source it was mapped to (``targets.parquet``) stand side by side; a timeline
plots each frame's joint error, confidence and keys (``frames.parquet``, ``keys.json``);
planted feet are coloured points and their slide is printed. Every frame's joints are
computed once when the folder is opened, so scrubbing and playback only move points.
Folders are named relative to the served folder and resolved by
:class:`~rigmap.studio.served_folder.ServedFolder`; nothing outside it is read.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.errors import RigmapError
from rigmap.map.outputs import SUMMARY_FORMAT
from rigmap.map.preview import subset_parents
from rigmap.studio.camera import CameraPose, aim_every_page, front_camera
from rigmap.studio.playback import FrameClock, PlaysFrames
from rigmap.studio.scene import SkeletonDrawing, to_scene
from rigmap.studio.served_folder import ServedFolder, StudioFileError

SCENE = "/review"
PICK = "(pick a map output)"
NONE_FOUND = "(no map output under the folder)"
RIG_COLOR = (40, 90, 200)
SOURCE_COLOR = (20, 20, 20)  # black, as the map's preview draws the targets
PLANTED_COLOR = (20, 170, 60)
LIFTED_COLOR = (200, 200, 200)
#: contact point size in scene units (m); ours, larger than a joint so it shows around it
CONTACT_SIZE = 0.05
#: gap between the rig and the source beside it, as a fraction of the rig's height; ours
GAP_OF_HEIGHT = 0.25
#: the names "rig" and "source" stand this far above the highest joint of the clip; ours
LABEL_ABOVE_CM = 8.0
#: the timeline's marker of the shown frame is redrawn at most this often in playback (s);
#: ours: a uPlot update redraws the whole chart, the skeletons need the bandwidth
PLOT_INTERVAL_S = 0.25


class ReviewError(RigmapError, ValueError):
    """A folder that is not a readable ``rigmap map`` output."""


@dataclass(frozen=True)
class ReviewClip:
    """One map output, every frame precomputed (world cm, Y up)."""

    name: str  # the folder relative to the served folder
    folder: Path
    summary: dict
    rig: object
    fps: float
    rig_joints: np.ndarray  # (F, J, 3): rig.pose of controls.parquet
    source_names: tuple[str, ...]  # the mapped joints (rig joint names)
    source_joints: np.ndarray | None  # (F, K, 3): targets.parquet, as written
    source_parents: np.ndarray  # (K,) nearest mapped ancestor within source_names, or -1
    offset_cm: np.ndarray  # (3,) where the source is drawn relative to where it is
    error_cm: np.ndarray  # (F,)
    confidence: np.ndarray | None  # (F,)
    planted: dict[str, np.ndarray]  # foot joint -> (F,) bool
    keys_per_frame: np.ndarray  # (F,) keys of every curve on each frame

    @property
    def n_frames(self) -> int:
        return len(self.rig_joints)

    def slide_cm(self, foot: str, frame: int) -> float | None:
        """How far the rig's ``foot`` moved on the ground since the previous frame, when it
        is planted on both (as ``rigmap.map.contacts.foot_skate`` averages it), else None."""
        planted = self.planted[foot]
        if frame == 0 or not (planted[frame] and planted[frame - 1]):
            return None
        j = list(self.rig.joint_names).index(foot)
        step = self.rig_joints[frame, j, [0, 2]] - self.rig_joints[frame - 1, j, [0, 2]]
        return float(np.linalg.norm(step))


def is_map_output(folder: Path) -> bool:
    """``summary.json`` of ``rigmap map``'s format beside a ``controls.parquet``."""
    try:
        summary = json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return False
    return (
        isinstance(summary, dict)
        and summary.get("format") == SUMMARY_FORMAT
        and (folder / "controls.parquet").is_file()
    )


def read_review(folder: Path, name: str, rigs: Callable[[str], object]) -> ReviewClip:
    """The clip of the map output ``folder`` (shown as ``name``); :class:`ReviewError`
    names the file and what is wrong with it."""
    summary_path = folder / "summary.json"
    try:
        summary = json.loads(summary_path.read_text())
    except FileNotFoundError:
        raise ReviewError(f"{name!r}: no summary.json; not a rigmap map output") from None
    except (OSError, ValueError) as error:
        raise ReviewError(f"{name}/summary.json: unreadable ({error})") from None
    if not isinstance(summary, dict) or summary.get("format") != SUMMARY_FORMAT:
        found = summary.get("format") if isinstance(summary, dict) else type(summary).__name__
        raise ReviewError(
            f"{name}/summary.json: format {found!r}, expected {SUMMARY_FORMAT!r} "
            "(a rigmap map output)"
        )
    rig_name = summary.get("rig")
    try:
        rig = rigs(str(rig_name))
    except Exception as error:  # an unknown or unloadable rig: named, the studio keeps serving
        raise ReviewError(f"{name}/summary.json: rig {rig_name!r}: {error}") from None
    controls = _table(folder, name, "controls.parquet")
    missing = [c for c in rig.control_names if c not in controls.columns]
    if missing:
        raise ReviewError(
            f"{name}/controls.parquet: lacks {len(missing)} controls of rig {rig.name!r} "
            f"(first {missing[0]!r})"
        )
    n_frames = len(controls)
    if n_frames == 0:
        raise ReviewError(f"{name}/controls.parquet: no frames")
    values = controls[list(rig.control_names)].to_numpy(dtype=np.float64)
    pose = rig.pose(values)
    rig_joints = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]

    frames = _table(folder, name, "frames.parquet", n_frames)
    if "joint_error_cm" not in frames.columns:
        raise ReviewError(f"{name}/frames.parquet: no joint_error_cm column")
    error_cm = frames["joint_error_cm"].to_numpy(dtype=np.float64)
    confidence = frames["confidence"].to_numpy(dtype=np.float64) if "confidence" in frames else None
    planted = {
        column.removeprefix("planted."): frames[column].to_numpy(dtype=bool)
        for column in frames.columns
        if column.startswith("planted.") and column.removeprefix("planted.") in rig.joint_names
    }

    source_names = tuple(str(j) for j in summary.get("mapped_joints") or ())
    source_joints = _source_joints(folder, name, source_names, n_frames)
    parents = (
        subset_parents(rig, source_names)
        if all(j in rig.joint_names for j in source_names)
        else np.full(len(source_names), -1)
    )
    fps = float(summary.get("fps") or 0.0)
    if not np.isfinite(fps) or fps <= 0:
        raise ReviewError(f"{name}/summary.json: fps {summary.get('fps')!r} is not positive")
    return ReviewClip(
        name=name,
        folder=folder,
        summary=summary,
        rig=rig,
        fps=fps,
        rig_joints=rig_joints,
        source_names=source_names,
        source_joints=source_joints,
        source_parents=parents,
        offset_cm=_beside(rig_joints, source_joints, float(rig.rest_height())),
        error_cm=error_cm,
        confidence=confidence,
        planted=planted,
        keys_per_frame=_keys_per_frame(folder, name, n_frames),
    )


def _source_joints(folder: Path, name: str, joints: tuple[str, ...], n_frames: int):
    """``targets.parquet`` as ``(F, K, 3)`` in ``joints``' order; None for a folder mapped
    before ``rigmap map`` wrote it."""
    if not (folder / "targets.parquet").is_file():
        return None
    targets = _table(folder, name, "targets.parquet", n_frames)
    columns = [f"{joint}.{axis}" for joint in joints for axis in "xyz"]
    absent = [c for c in columns if c not in targets.columns]
    if absent or not columns:
        raise ReviewError(
            f"{name}/targets.parquet: lacks the columns of summary.json's mapped_joints "
            f"(first {(absent or ['<none listed>'])[0]!r})"
        )
    return targets[columns].to_numpy(dtype=np.float64).reshape(n_frames, -1, 3)


def _table(folder: Path, name: str, file: str, n_frames: int | None = None) -> pd.DataFrame:
    try:
        table = pd.read_parquet(folder / file)
    except FileNotFoundError:
        raise ReviewError(f"{name!r}: no {file}; not a whole rigmap map output") from None
    except Exception as error:  # pyarrow raises several kinds for a damaged file
        raise ReviewError(f"{name}/{file}: unreadable ({error})") from None
    if "frame" in table.columns:
        table = table.sort_values("frame", kind="stable").reset_index(drop=True)
    if n_frames is not None and len(table) != n_frames:
        raise ReviewError(f"{name}/{file}: {len(table)} frames, controls.parquet has {n_frames}")
    return table


def _keys_per_frame(folder: Path, name: str, n_frames: int) -> np.ndarray:
    counts = np.zeros(n_frames, dtype=np.int64)
    path = folder / "keys.json"
    if not path.is_file():
        return counts
    try:
        curves = json.loads(path.read_text())["curves"]
        frames = [round(float(key["frame"])) for keys in curves.values() for key in keys]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ReviewError(f"{name}/keys.json: unreadable ({error})") from None
    inside = [f for f in frames if 0 <= f < n_frames]
    np.add.at(counts, np.asarray(inside, dtype=np.int64), 1)
    return counts


def _beside(rig_joints: np.ndarray, source_joints, height_cm: float) -> np.ndarray:
    """Shift the source along +X past everything the rig and it cover over the clip, so the
    two never overlap however the character moves."""
    if source_joints is None:
        return np.zeros(3)
    both = np.concatenate([rig_joints[..., 0].ravel(), source_joints[..., 0].ravel()])
    return np.array([float(np.ptp(both)) + GAP_OF_HEIGHT * height_cm, 0.0, 0.0])


@dataclass(frozen=True)
class _Hierarchy:
    """The parents of the source's joints: all a :class:`SkeletonDrawing` reads of a rig."""

    parents: np.ndarray


class ReviewView(PlaysFrames):
    """The view; ``served`` is where map outputs are found, ``rigs(name)`` gives a rig (e.g.
    :func:`rigmap.rigs.load`), asked for once per name; the rigs stay the caller's to close
    (``load`` shares one built-in rig with every other user of it)."""

    name = "Review"

    def __init__(self, served: ServedFolder, rigs: Callable[[str], object]):
        self.served = served
        self._load_rig = rigs
        self._rigs: dict[str, object] = {}
        self.clip: ReviewClip | None = None
        self.frame = 0  # the frame shown
        self.shown = 0  # frames shown since the page was built (playback and scrubbing)
        self.camera: CameraPose | None = None
        self.rig_drawing: SkeletonDrawing | None = None
        self.source_drawing: SkeletonDrawing | None = None
        self._contacts = None
        self._labels = []
        self._visible = True
        self._lock = threading.RLock()  # the page's callbacks and the playback thread
        self._clock = FrameClock("studio-review")
        self._plot_at = 0.0

    # ------------------------------------------------------------------ page
    def build(self, server, gui) -> None:
        self.server = server
        self.menu = gui.add_dropdown("Map output", options=self._menu_options())
        self.rescan = gui.add_button("Rescan folder")
        self.typed = gui.add_text(
            "Folder", "", hint="a map output folder, relative to the served one"
        )
        self.open_button = gui.add_button("Open folder")
        self.message = gui.add_markdown("")
        self.status = gui.add_markdown("Pick a map output.")
        self.slider = gui.add_slider("Frame", min=0, max=1, step=1, initial_value=0, disabled=True)
        self.play_button = gui.add_button("Play", disabled=True)
        self.loop = gui.add_checkbox("Loop", initial_value=True)
        self.contacts_text = gui.add_markdown("")
        self.timeline = self._add_timeline(gui)
        self.menu.on_update(lambda _event: self._picked())
        self.rescan.on_click(lambda _event: self._rescan())
        self.open_button.on_click(lambda _event: self.open(self.typed.value))
        self.slider.on_update(self._scrubbed)
        self.play_button.on_click(lambda _event: self.toggle())
        self._clock.start()

    def show(self, visible: bool) -> None:
        self._visible = visible
        if not visible:
            self.pause()
        for handle in (self.rig_drawing, self.source_drawing, self._contacts, *self._labels):
            if handle is not None:
                handle.visible = visible
        if visible and self.camera is not None:
            aim_every_page(self.camera, self.server)

    def close(self) -> None:
        self._clock.close()

    # ------------------------------------------------------------------ folders
    def map_outputs(self) -> list[str]:
        """The map output folders under the served folder (relative)."""
        found = self.served.folders_with("summary.json")
        return [name for name in found if is_map_output(self.served.root / name)]

    def _menu_options(self) -> list[str]:
        found = self.map_outputs()
        return [PICK, *found] if found else [NONE_FOUND]

    def _rescan(self) -> None:
        self.menu.options = self._menu_options()

    def _picked(self) -> None:
        if self.menu.value not in (PICK, NONE_FOUND):
            self.open(self.menu.value)

    def rig(self, name: str):
        if name not in self._rigs:
            self._rigs[name] = self._load_rig(name)
        return self._rigs[name]

    def open(self, requested: str) -> ReviewClip | None:
        """Load the map output ``requested`` (relative to the served folder) and show its
        first frame; a refused or unreadable folder is shown in the page and returned None."""
        self.pause()
        try:
            folder = self.served.resolve(requested, kind="folder")
            name = self.served.relative(folder) or "."
            self.message.content = f"Loading {name}…"
            clip = read_review(folder, name, self.rig)
        except (StudioFileError, ReviewError) as error:
            self.message.content = f"**Not opened:** {error}"
            return None
        with self._lock:
            self._clear()
            self.clip = clip
            self.frame = 0
            self._draw(clip)
        self.message.content = self._headline(clip)
        self._frame_camera(clip)
        self.slider.value = 0
        self.slider.max = max(clip.n_frames - 1, 1)
        self.slider.disabled = clip.n_frames < 2
        self.play_button.disabled = clip.n_frames < 2
        self._timeline(clip)
        self.show_frame(0)
        return clip

    @staticmethod
    def _headline(clip: ReviewClip) -> str:
        s = clip.summary
        line = (
            f"**{clip.name}**: rig {clip.rig.name} ← {Path(str(s.get('source', '?'))).name} · "
            f"{clip.n_frames} frames at {clip.fps:.3g} fps · joint error "
            f"{_number(s.get('joint_error_rms_cm'))} cm RMS · "
            f"{s.get('keys', '?')} keys on {s.get('keyed_controls', '?')} controls · skate "
            f"{_number(s.get('foot_skate_result_cm_per_frame'), 3)} cm/frame (source "
            f"{_number(s.get('foot_skate_source_cm_per_frame'), 3)})"
        )
        if clip.source_joints is None:
            line += (
                "\n\nNo targets.parquet (an older rigmap map wrote this folder): the rig is "
                "shown alone; map the clip again to see its source beside it."
            )
        else:
            line += "\n\nBlue: the rig · black: the retargeted source (right) · green: planted"
        return line

    # ------------------------------------------------------------------ scene
    def _clear(self) -> None:
        for handle in (self.rig_drawing, self.source_drawing, self._contacts, *self._labels):
            if handle is not None:
                handle.remove()
        self.rig_drawing, self.source_drawing, self._contacts, self._labels = None, None, None, []

    def _draw(self, clip: ReviewClip) -> None:
        scene = self.server.scene
        self.rig_drawing = SkeletonDrawing(
            scene, f"{SCENE}/rig", clip.rig, clip.rig_joints[0], color=RIG_COLOR
        )
        tops = [(clip.rig_joints, "rig")]
        if clip.source_joints is not None:
            self.source_drawing = SkeletonDrawing(
                scene,
                f"{SCENE}/source",
                _Hierarchy(clip.source_parents),
                clip.source_joints[0] + clip.offset_cm,
                color=SOURCE_COLOR,
            )
            tops.append((clip.source_joints + clip.offset_cm, "source"))
        for joints, text in tops:
            above = np.array(
                [
                    joints[..., 0].mean(),
                    joints[..., 1].max() + LABEL_ABOVE_CM,
                    joints[..., 2].mean(),
                ]
            )
            self._labels.append(
                scene.add_label(
                    f"{SCENE}/labels/{text}",
                    text,
                    position=tuple(to_scene(above)),
                    anchor="bottom-center",
                )
            )
        if clip.planted:
            points, colors = self._contact_points(clip, 0)
            self._contacts = scene.add_point_cloud(
                f"{SCENE}/contacts",
                points=points,
                colors=colors,
                point_size=CONTACT_SIZE,
                point_shape="circle",
            )
        for handle in (self.rig_drawing, self.source_drawing, self._contacts, *self._labels):
            if handle is not None:
                handle.visible = self._visible

    def _contact_points(self, clip: ReviewClip, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """The feet of the rig (and of the source) at ``frame``, green where planted."""
        points, colors = [], []
        names = list(clip.rig.joint_names)
        for foot, planted in clip.planted.items():
            color = PLANTED_COLOR if planted[frame] else LIFTED_COLOR
            points.append(clip.rig_joints[frame, names.index(foot)])
            colors.append(color)
            if clip.source_joints is not None and foot in clip.source_names:
                k = clip.source_names.index(foot)
                points.append(clip.source_joints[frame, k] + clip.offset_cm)
                colors.append(color)
        return to_scene(np.array(points)), np.array(colors, dtype=np.uint8)

    def _frame_camera(self, clip: ReviewClip) -> None:
        """Every page's camera (and a new page's) in front of both skeletons, whole clip."""
        points = [clip.rig_joints.reshape(-1, 3)]
        if clip.source_joints is not None:
            points.append((clip.source_joints + clip.offset_cm).reshape(-1, 3))
        self.camera = front_camera(to_scene(np.concatenate(points)))
        aim_every_page(self.camera, self.server)

    # ------------------------------------------------------------------ timeline
    def _add_timeline(self, gui):
        """An empty, hidden chart, made with the page (inside the view's folder); a folder
        opened later fills it."""
        from viser import uplot

        empty = tuple(np.zeros(2) for _ in range(5))
        series = (uplot.Series(label="frame"), *(uplot.Series() for _ in range(4)))
        return gui.add_uplot(
            empty,
            series,
            aspect=1.6,
            visible=False,
            title="per frame: joint error, confidence, keys",
        )

    def _timeline(self, clip: ReviewClip) -> None:
        """Joint error (cm, left axis), confidence (0-1, right axis) and the keys on each
        frame (orange points, own scale) against the frame; a red dot marks the frame shown."""
        from viser import uplot

        frames = np.arange(clip.n_frames, dtype=np.float64)
        confidence = clip.confidence if clip.confidence is not None else np.zeros(clip.n_frames)
        keys = clip.keys_per_frame.astype(np.float64)
        self.timeline.data = (frames, clip.error_cm, confidence, keys, clip.error_cm)
        self.timeline.series = (
            uplot.Series(label="frame"),
            uplot.Series(label="joint error (cm)", stroke="#2856c8", width=2, scale="cm"),
            uplot.Series(
                label="confidence",
                stroke="#2a9d3c",
                width=2,
                scale="confidence",
                show=clip.confidence is not None,
            ),
            uplot.Series(
                label="keys",
                stroke="#e08a00",
                width=0,
                scale="keys",
                points=uplot.Series_Points(show=True, size=6, fill="#e08a00"),
            ),
            self._marker(0),
        )
        self.timeline.scales = {
            "x": uplot.Scale(time=False, range=(0.0, float(max(clip.n_frames - 1, 1)))),
            "cm": uplot.Scale(range=(0.0, float(max(clip.error_cm.max(), 1e-3) * 1.1))),
            "confidence": uplot.Scale(range=(0.0, 1.0)),
            "keys": uplot.Scale(range=(0.0, float(max(keys.max(), 1.0) * 1.1))),
        }
        self.timeline.axes = (
            uplot.Axis(label="frame"),
            uplot.Axis(scale="cm", label="joint error (cm)", side=3),
            uplot.Axis(scale="confidence", label="confidence", side=1, grid={"show": False}),
        )
        self.timeline.visible = True

    @staticmethod
    def _marker(frame: int):
        from viser import uplot

        return uplot.Series(
            label="shown frame",
            stroke="#d02020",
            width=0,
            scale="cm",
            points=uplot.Series_Points(show=True, size=11, fill="#d02020", filter=(frame,)),
        )

    # ------------------------------------------------------------------ frames
    def _scrubbed(self, event) -> None:
        if event.client_id is not None and self._clock.playing:  # a scrub during playback
            self._clock.rewind(int(self.slider.value))
        self.show_frame(int(self.slider.value))

    def show_frame(self, frame: int) -> None:
        """Pose both skeletons and the contacts at ``frame``; update the status."""
        with self._lock:
            clip = self.clip
            if clip is None:
                return
            frame = int(np.clip(frame, 0, clip.n_frames - 1))
            self.frame = frame
            self.shown += 1
            self.rig_drawing.update(clip.rig_joints[frame])
            if self.source_drawing is not None:
                self.source_drawing.update(clip.source_joints[frame] + clip.offset_cm)
            if self._contacts is not None:
                points, colors = self._contact_points(clip, frame)
                self._contacts.points = points
                self._contacts.colors = colors
            self.status.content = self.status_line(clip, frame)
            self.contacts_text.content = self.contacts_line(clip, frame)
            now = time.monotonic()
            if not self._clock.playing or now - self._plot_at >= PLOT_INTERVAL_S:
                self._plot_at = now
                self.timeline.series = (*self.timeline.series[:-1], self._marker(frame))

    @staticmethod
    def status_line(clip: ReviewClip, frame: int) -> str:
        confidence = "–" if clip.confidence is None else f"{clip.confidence[frame]:.2f}"
        return (
            f"frame {frame} / {clip.n_frames - 1} · joint error {clip.error_cm[frame]:.2f} cm · "
            f"confidence {confidence} · {int(clip.keys_per_frame[frame])} keys"
        )

    @staticmethod
    def contacts_line(clip: ReviewClip, frame: int) -> str:
        """Each foot planted or lifted; a planted foot's slide since the previous frame."""
        parts = []
        for foot, planted in clip.planted.items():
            if not planted[frame]:
                parts.append(f"{foot} lifted")
                continue
            slide = clip.slide_cm(foot, frame)
            parts.append(f"{foot} planted" + ("" if slide is None else f", slid {slide:.3f} cm"))
        return "Feet: " + " · ".join(parts) if parts else "No foot contacts in frames.parquet."

    # ------------------------------------------------------------------ playback
    def play(self) -> None:
        """Play from the frame shown (from the start when it is the last) at the clip's fps."""
        clip = self.clip
        if clip is None or clip.n_frames < 2:
            return
        start = 0 if self.frame >= clip.n_frames - 1 else self.frame
        if start != self.frame:
            self.slider.value = start

        def tick(frame: int) -> None:
            if frame != self.frame and clip is self.clip:
                self.slider.value = frame

        def ended() -> None:
            self.slider.value = clip.n_frames - 1
            self.play_button.label = "Play"
            self.show_frame(self.frame)

        self._clock.play(
            start, clip.n_frames, clip.fps, tick, loop=lambda: self.loop.value, ended=ended
        )
        self.play_button.label = "Pause"

    def pause(self) -> None:
        if self._clock.pause():
            self.play_button.label = "Play"
            self.show_frame(self.frame)  # the timeline's marker on the frame it stopped at


def _number(value, digits: int = 2) -> str:
    return f"{value:.{digits}f}" if isinstance(value, int | float) else "?"
