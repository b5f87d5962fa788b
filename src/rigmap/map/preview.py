"""A mapped clip at a glance: the target skeleton drawn over the rig's result.

``preview.png`` is a contact sheet of evenly spaced frames and ``preview.gif`` plays the
clip; in both the rig's joints at the mapped controls are drawn as
:func:`rigmap.viz.skeleton.draw_skeleton` draws any pose (left blue, right red), and the
targets the map was given (the retarget map's joints, or the effectors) in black over
them, bones joining each mapped joint to its nearest mapped ancestor. Where black and
colour part, the mapping missed. The camera follows the character (side view, Y up);
each panel names its frame and its RMS joint error in cm.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

TARGET_COLOR = "black"
GIF_MAX_FRAMES = 48  # frames of the GIF; a longer clip is played every k-th frame (ours)
PANEL_INCHES = 2.4


def subset_parents(rig, joints) -> np.ndarray:
    """For each of ``joints``, the index (within ``joints``) of its nearest ancestor among
    them in the rig's hierarchy, or -1."""
    position = {name: k for k, name in enumerate(joints)}
    parents = np.full(len(joints), -1)
    if rig.parents is None:
        return parents
    for k, name in enumerate(joints):
        ancestor = int(rig.parents[rig.joint_names.index(name)])
        while ancestor >= 0 and rig.joint_names[ancestor] not in position:
            ancestor = int(rig.parents[ancestor])
        if ancestor >= 0:
            parents[k] = position[rig.joint_names[ancestor]]
    return parents


def write_preview(
    folder: str | os.PathLike, rig, result, *, panels: int = 8, columns: int = 4, view: str = "side"
) -> list[Path]:
    """Write ``preview.png`` and ``preview.gif`` of ``result`` (a MapResult) into ``folder``."""
    folder = Path(folder)
    pose = rig.pose(result.controls)
    world = np.asarray(pose.positions) + np.asarray(pose.cog)[:, None, :]
    scene = _Scene(
        rig,
        world,
        result.targets,
        subset_parents(rig, result.joint_names),
        result.frame_error_cm,
        view,
    )
    title = f"{rig.name} <- {Path(result.source).name} (black: targets)"
    return [
        _contact_sheet(scene, folder / "preview.png", panels, columns, title),
        _gif(scene, folder / "preview.gif", result.fps, title),
    ]


class _Scene:
    """What every frame draws and the fixed window size that follows the character."""

    def __init__(self, rig, world, targets, target_parents, error_cm, view):
        from rigmap.viz.skeleton import project

        self.rig, self.world, self.targets = rig, world, targets
        self.target_parents, self.error_cm, self.view = target_parents, error_cm, view
        horizontal = np.array([project(p, view)[0] for p in world])
        vertical = np.array([project(p, view)[1] for p in world])
        self.centers = 0.5 * (horizontal.min(axis=1) + horizontal.max(axis=1))
        spread = float(np.max(horizontal.max(axis=1) - horizontal.min(axis=1)))
        height = float(np.ptp(vertical))
        margin = 0.1 * max(spread, height, 1.0)
        self.half_width = 0.5 * max(spread, 0.6 * height) + margin
        self.bottom = min(float(vertical.min()), 0.0) - margin
        self.top = float(vertical.max()) + margin

    @property
    def aspect(self) -> float:
        return float(np.clip(2 * self.half_width / (self.top - self.bottom), 0.5, 2.0))

    def draw(self, ax, index: int) -> None:
        from rigmap.viz.skeleton import draw_skeleton

        ax.clear()
        ax.set_axis_off()
        ax.axhline(0.0, color="0.6", lw=0.8, zorder=0)
        draw_skeleton(
            ax,
            self.world[index],
            self.rig.parents,
            self.view,
            joint_names=self.rig.joint_names,
            joint_size=4.0,
            linewidth=1.4,
        )
        draw_skeleton(
            ax,
            self.targets[index],
            self.target_parents,
            self.view,
            color=TARGET_COLOR,
            alpha=0.75,
            joint_size=7.0,
            linewidth=0.9,
        )
        center = self.centers[index]
        ax.set_xlim(center - self.half_width, center + self.half_width)
        ax.set_ylim(self.bottom, self.top)
        ax.set_aspect("equal")
        ax.text(
            0.02,
            0.97,
            f"{index}  {self.error_cm[index]:.1f} cm",
            transform=ax.transAxes,
            va="top",
            fontsize=7,
            color="0.25",
        )


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _contact_sheet(scene: _Scene, out: Path, panels: int, columns: int, title: str) -> Path:
    from rigmap.viz.atomic import save_and_close

    plt = _pyplot()
    frames = len(scene.world)
    picks = np.unique(np.linspace(0, frames - 1, min(panels, frames)).round().astype(int))
    columns = min(columns, len(picks))
    rows = int(np.ceil(len(picks) / columns))
    fig, axes = plt.subplots(
        rows,
        columns,
        squeeze=False,
        figsize=(PANEL_INCHES * columns * scene.aspect, PANEL_INCHES * rows + 0.5),
    )
    for ax in axes.ravel():
        ax.set_axis_off()
    for ax, index in zip(axes.ravel(), picks, strict=False):
        scene.draw(ax, int(index))
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return save_and_close(fig, out, dpi=90)


def _gif(scene: _Scene, out: Path, fps: float, title: str) -> Path:
    from rigmap.viz.gif import write_figure_gif

    plt = _pyplot()
    step = max(1, int(np.ceil(len(scene.world) / GIF_MAX_FRAMES)))
    fig, ax = plt.subplots(figsize=(3.4 * scene.aspect, 3.4), dpi=72)

    def draw(index: int) -> None:
        scene.draw(ax, index)
        ax.set_title(title, fontsize=7)

    try:
        frames = range(0, len(scene.world), step)
        duration = max(20, round(1000 * step / fps))
        return write_figure_gif(fig, draw, frames, out, duration_ms=duration)
    finally:
        plt.close(fig)


def render_pose(
    rig, controls: np.ndarray, targets: np.ndarray, subset, out: str | os.PathLike, *, title: str
) -> Path:
    """One pose from front, side and top with its effector targets ringed in black; a mesh
    rig (the face) is drawn shaded instead (:func:`rigmap.viz.mesh.render_mesh_views`)."""
    if rig.parents is None:
        from rigmap.viz.mesh import render_mesh_views

        return render_mesh_views(rig, controls, out, title=title)
    from rigmap.viz.atomic import save_and_close
    from rigmap.viz.skeleton import VIEWS, draw_skeleton, project

    plt = _pyplot()
    pose = rig.pose(np.asarray(controls, dtype=np.float64)[None])
    world = np.asarray(pose.positions)[0] + np.asarray(pose.cog)[0]
    fig, axes = plt.subplots(1, 3, figsize=(13, 5))
    for ax, view in zip(axes, VIEWS, strict=True):
        draw_skeleton(ax, world, rig.parents, view, joint_names=rig.joint_names)
        x, y = project(np.asarray(targets), view)
        ax.scatter(x, y, s=70, facecolors="none", edgecolors=TARGET_COLOR, linewidths=1.2, zorder=4)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(view)
        ax.grid(alpha=0.2)
    fig.suptitle(title)
    fig.tight_layout()
    return save_and_close(fig, out, dpi=90)
