"""Look at a clip: a contact sheet (a grid of frames) and an animated GIF.

Skeleton rigs are drawn with :func:`rigmap.viz.skeleton.draw_skeleton` in world
space (joint positions plus the COG placement), seen from the character's side by
default, over a ground line with ticks every 10 cm that stay put in the world: a
planted foot stays on its tick while the body travels, a sliding one drifts. Feet on
the ground (within 2 cm) are ringed, and under the grid a strip plots each foot's
height over the whole clip, so plants (flat at zero) and swings read at a glance.
Mesh rigs (``rig.faces`` is set) are drawn shaded with :mod:`rigmap.viz.mesh`.

``show_clip`` is what ``rigmap corpus show`` calls.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigmap.animation.clip import Clip

CONTACT_HEIGHT_CM = 2.0
GROUND_TICK_CM = 10.0
GIF_MAX_FRAMES = 72
GIF_MAX_FRAMES_MESH = 36
PANEL_SIZE_IN = 2.3
MESH_PIXELS = 200


@dataclass
class PlayedClip:
    """A clip evaluated on its rig, ready to draw: world positions per played frame."""

    rig: object
    clip_name: str
    frames: np.ndarray  # (F,) whole frames
    fps: int
    controls: np.ndarray  # (F, C) full control vectors
    world: np.ndarray  # (F, J, 3) joint positions in world space (cm)
    cog: np.ndarray  # (F, 3) centre of gravity in world space (cm)

    @property
    def is_mesh(self) -> bool:
        return getattr(self.rig, "faces", None) is not None and hasattr(self.rig, "mesh")

    def mesh_world(self, index: int) -> np.ndarray:
        """``(V, 3)`` world vertices of one frame of a mesh rig."""
        return np.asarray(self.rig.mesh(self.controls[index][None]))[0] + self.cog[index]


def play_clip(rig, clip: Clip) -> PlayedClip:
    """Evaluate ``clip`` on ``rig`` at every whole frame (unkeyed controls at default)."""
    Y = clip.evaluate(rig.control_names, rig.controls.defaults)
    pose = rig.pose(Y)
    cog = np.asarray(pose.cog)
    world = np.asarray(pose.positions) + cog[:, None, :]
    return PlayedClip(rig, clip.name, clip.frames, clip.fps, Y, world, cog)


def show_clip(
    rig_name: str,
    clip_name: str,
    out_path: str | os.PathLike,
    *,
    split: str | None = None,
    seed: int = 0,
    panels: int = 12,
    columns: int = 6,
    view: str | None = None,
) -> list[Path]:
    """Draw a library clip of a built-in rig; returns the files written.

    ``out_path`` ending in ``.gif`` writes only the animation; anything else writes a
    PNG contact sheet there and the GIF beside it (same name, ``.gif``). ``split``
    ("train"/"test") is checked when given; ``seed`` is the corpus seed, so the
    drawing shows exactly the frames the corpus holds for that seed. ``panels`` frames
    are laid out ``columns`` to a row; ``view`` is "side", "front" or "top" (default:
    side, front for the face).
    """
    from rigmap.animation.library import build_clip, motion_library
    from rigmap.rigs import load

    rig = load(rig_name)
    library = motion_library(rig.name)
    found_split, motion = library.find(clip_name)
    if split is not None and split != found_split:
        raise KeyError(
            f"clip {clip_name!r} of rig {rig.name!r} is in the {found_split!r} split, not {split!r}"
        )
    played = play_clip(rig, build_clip(rig.name, motion, seed=seed))
    out = Path(out_path)
    title = f"{rig.name} — {clip_name} ({found_split} clip, seed {seed})"
    if out.suffix.lower() == ".gif":
        return [write_gif(played, out, view=view, title=title)]
    sheet = write_contact_sheet(played, out, panels=panels, columns=columns, view=view, title=title)
    return [sheet, write_gif(played, out.with_suffix(".gif"), view=view, title=title)]


# --- the contact sheet ----------------------------------------------------------------
def write_contact_sheet(
    played: PlayedClip,
    out_path: str | os.PathLike,
    *,
    panels: int = 12,
    columns: int = 6,
    view: str | None = None,
    title: str | None = None,
) -> Path:
    """A PNG grid of ``panels`` evenly spaced frames (frame numbers in the corners) and,
    for a character with feet, a strip of foot heights over the whole clip."""
    plt = _pyplot()
    from rigmap.viz.atomic import save_and_close

    if panels < 1 or columns < 1:
        raise ValueError(f"panels and columns must be >= 1, got {panels} and {columns}")
    view = view or _default_view(played)
    picks = np.unique(
        np.linspace(0, len(played.frames) - 1, min(panels, len(played.frames))).round()
    ).astype(int)
    columns = min(columns, len(picks))
    rows = int(np.ceil(len(picks) / columns))
    camera = _Camera.fit(played, view)
    feet = _feet(played) if view != "top" else []
    strip = 1.3 if feet else 0.0
    panel_h = PANEL_SIZE_IN
    fig = plt.figure(
        figsize=(PANEL_SIZE_IN * columns * camera.aspect, panel_h * rows + strip + 0.6)
    )
    grid = fig.add_gridspec(
        rows + (1 if feet else 0),
        columns,
        height_ratios=[panel_h] * rows + ([strip] if feet else []),
    )
    for k, index in enumerate(picks):
        ax = fig.add_subplot(grid[k // columns, k % columns])
        ax.set_axis_off()
        _draw_frame(ax, played, int(index), view, camera)
    if feet:
        _draw_foot_strip(fig.add_subplot(grid[rows, :]), played, feet, picks)
    fig.suptitle(title or f"{played.rig.name} — {played.clip_name}", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    return save_and_close(fig, out_path, dpi=100)


def write_gif(
    played: PlayedClip,
    out_path: str | os.PathLike,
    *,
    view: str | None = None,
    title: str | None = None,
    max_frames: int | None = None,
) -> Path:
    """An animated GIF at the clip's speed (every k-th frame when the clip is long)."""
    from rigmap.viz.gif import write_figure_gif

    plt = _pyplot()
    view = view or _default_view(played)
    if max_frames is None:
        max_frames = GIF_MAX_FRAMES_MESH if played.is_mesh else GIF_MAX_FRAMES
    step = max(1, int(np.ceil(len(played.frames) / max_frames)))
    camera = _Camera.fit(played, view)
    fig, ax = plt.subplots(figsize=(3.6 * camera.aspect, 3.6), dpi=80)

    def draw(index: int) -> None:
        ax.clear()
        ax.set_axis_off()
        _draw_frame(ax, played, index, view, camera)
        if title:
            ax.set_title(title, fontsize=8)

    try:
        frames = range(0, len(played.frames), step)
        duration = round(1000 * step / played.fps)
        return write_figure_gif(fig, draw, frames, out_path, duration_ms=duration)
    finally:
        plt.close(fig)


# --- drawing one frame -------------------------------------------------------------------
@dataclass(frozen=True)
class _Camera:
    """What part of the world each panel shows: a fixed window, or one that follows the COG."""

    half_width: float
    bottom: float
    top: float
    follow: bool
    center: float
    ground: bool

    @property
    def aspect(self) -> float:
        return float(np.clip(2 * self.half_width / (self.top - self.bottom), 0.6, 2.2))

    @classmethod
    def fit(cls, played: PlayedClip, view: str) -> _Camera:
        from rigmap.viz.skeleton import project

        if played.is_mesh:
            sample = np.linspace(0, len(played.frames) - 1, min(10, len(played.frames)))
            points = [played.mesh_world(int(i)) for i in sample.round()]
        else:
            points = list(played.world)
        horizontal, vertical = zip(*(project(p, view) for p in points), strict=True)
        horizontal, vertical = np.array(horizontal), np.array(vertical)
        centers = np.array([project(c[None], view)[0][0] for c in played.cog])
        body = float(np.max(horizontal.max(axis=1) - horizontal.min(axis=1)))
        height = float(np.ptp(vertical))
        travel = float(np.ptp(centers))
        margin = 0.08 * max(body, height, 1.0)
        follow = travel > 0.6 * body
        half = 0.5 * (body if follow else float(np.ptp(horizontal))) + margin
        lowest = float(vertical.min())
        ground = view != "top" and -2.0 <= lowest <= 0.05 * height + 1.0
        bottom = (min(lowest, 0.0) if ground else lowest) - margin
        top = float(vertical.max()) + margin
        center = 0.5 * (float(horizontal.min()) + float(horizontal.max()))
        return cls(half, bottom, top, follow, center, ground)

    def window(self, horizontal_center: float) -> tuple[float, float]:
        center = horizontal_center if self.follow else self.center
        return center - self.half_width, center + self.half_width


def _draw_frame(ax, played: PlayedClip, index: int, view: str, camera: _Camera) -> None:
    from rigmap.viz.skeleton import draw_skeleton, project

    world = played.world[index]
    horizontal, vertical = project(world, view)
    cog_h = float(project(played.cog[index][None], view)[0][0])
    left, right = camera.window(cog_h)
    if camera.ground:
        ax.axhline(0.0, color="0.55", lw=0.9, zorder=0)
        ticks = np.arange(np.floor(left / GROUND_TICK_CM), np.ceil(right / GROUND_TICK_CM) + 1)
        for tick in ticks * GROUND_TICK_CM:
            ax.plot([tick, tick], [0.0, -2.0], color="0.55", lw=0.7, zorder=0)
    if played.is_mesh:
        _draw_mesh(ax, played, index, view, (left, right), (camera.bottom, camera.top))
    else:
        draw_skeleton(
            ax,
            world,
            played.rig.parents,
            view,
            joint_names=played.rig.joint_names,
            joint_size=4.0,
            linewidth=1.3,
        )
        if camera.ground:
            touching = _leaves(played.rig) & (world[:, 1] < CONTACT_HEIGHT_CM)
            ax.scatter(
                horizontal[touching],
                vertical[touching],
                s=28,
                facecolors="none",
                edgecolors="black",
                linewidths=0.8,
                zorder=4,
            )
    ax.set_xlim(left, right)
    ax.set_ylim(camera.bottom, camera.top)
    ax.set_aspect("equal")
    ax.text(
        0.02,
        0.97,
        f"{played.frames[index]}",
        transform=ax.transAxes,
        va="top",
        fontsize=8,
        color="0.25",
    )


def _leaves(rig) -> np.ndarray:
    parents = np.asarray(rig.parents)
    has_child = np.zeros(len(parents), dtype=bool)
    has_child[parents[parents >= 0]] = True
    return ~has_child


def _feet(played: PlayedClip) -> list[int]:
    """End joints that touch the ground during the clip, one per foot (not every toe)."""
    if played.is_mesh or played.rig.parents is None:
        return []
    touching = _leaves(played.rig) & (played.world[:, :, 1].min(axis=0) < CONTACT_HEIGHT_CM)
    names = played.rig.joint_names
    return [j for j in np.flatnonzero(touching) if not re.search(r"_\d+$", names[j])]


def _draw_foot_strip(ax, played: PlayedClip, feet: list[int], picks: np.ndarray) -> None:
    from rigmap.viz.skeleton import side_colors

    names = [played.rig.joint_names[j] for j in feet]
    colors = side_colors(names)
    styles = ["-", "--", "-.", ":"]
    fronts = sorted({n.split("_")[0] for n in names})
    for j, name, color in zip(feet, names, colors, strict=True):
        style = styles[fronts.index(name.split("_")[0]) % len(styles)]
        ax.plot(played.frames, played.world[:, j, 1], style, color=color, lw=1.2, label=name)
    for index in picks:
        ax.axvline(played.frames[index], color="0.85", lw=0.6, zorder=0)
    ax.axhline(0.0, color="0.55", lw=0.8)
    ax.set_xlim(played.frames[0], played.frames[-1])
    ax.set_xlabel(f"frame ({played.fps} fps)", fontsize=8)
    ax.set_ylabel("foot height (cm)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, ncol=len(feet), loc="upper right", frameon=False)


def _draw_mesh(ax, played: PlayedClip, index: int, view: str, xlim, ylim) -> None:
    """Shaded mesh via the z-buffer rasteriser, placed in world coordinates."""
    from rigmap.viz.mesh import VIEWS, rasterise

    rig = played.rig
    camera_view = {v.name: v for v in VIEWS}[view]
    vertices = played.mesh_world(index)
    width = max(xlim[1] - xlim[0], ylim[1] - ylim[0])
    cm_per_pixel = width / MESH_PIXELS
    # the rasteriser centres its square picture on `center` (camera coordinates)
    center = np.array([0.5 * (xlim[0] + xlim[1]), 0.5 * (ylim[0] + ylim[1]), 0.0])
    faces = np.asarray(rig.faces)
    colors = getattr(rig, "face_colors", None)
    if colors is None:
        colors = np.tile((0.78, 0.74, 0.70), (len(faces), 1))
    image, depth = rasterise(
        vertices, faces, colors, camera_view, center, cm_per_pixel, MESH_PIXELS
    )
    alpha = np.isfinite(depth)[..., None].astype(float)
    half = 0.5 * width
    ax.imshow(
        np.concatenate([image, alpha], axis=-1),
        extent=(center[0] - half, center[0] + half, center[1] - half, center[1] + half),
        interpolation="lanczos",
        zorder=2,
    )


def _default_view(played: PlayedClip) -> str:
    return "front" if played.rig.name == "face" else "side"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
