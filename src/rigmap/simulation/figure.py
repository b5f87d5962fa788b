"""Fig. 9's picture: the simulated squirrel beside the rig mapped onto it, a few frames.

Top row the simulation (Blender's soft body), bottom row the rig at the mapped controls,
both seen from the character's right side by one fixed camera (the same centimetres per
pixel in every panel, so the drop, the squash and the push read as motion), each panel
titled with its frame, the vertex error and the teeth vertices inside the body; below, the
per-frame vertex error and the simulated squirrel's height.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.viz.atomic import save_and_close
from rigmap.viz.mesh import VIEWS, rasterise

SIDE = next(view for view in VIEWS if view.name == "side")
PIXELS = 220


def simulation_figure(
    rig,
    simulated: np.ndarray,
    mapped: np.ndarray,
    frames: pd.DataFrame,
    picks: list[int],
    out_path,
    *,
    fps: float,
) -> Path:
    """Draw the figure (module docstring) for frames ``picks`` into the PNG ``out_path``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    picks = sorted({min(max(int(p), 0), len(simulated) - 1) for p in picks})
    faces, colors = np.asarray(rig.faces), np.asarray(rig.face_colors)
    both = np.concatenate([simulated[picks], mapped[picks]]) @ SIDE.axes.T
    low, high = both.reshape(-1, 3).min(axis=0), both.reshape(-1, 3).max(axis=0)
    center = 0.5 * (low + high)
    cm_per_pixel = 1.1 * float(max(high[:2] - low[:2])) / PIXELS
    fig = plt.figure(figsize=(2.3 * len(picks), 6.6))
    grid = fig.add_gridspec(3, len(picks), height_ratios=[1, 1, 0.8])
    rows = (
        ("simulation", simulated, "teeth_inside_simulation"),
        ("rig", mapped, "teeth_inside_rig"),
    )
    for row, (label, meshes, teeth) in enumerate(rows):
        for col, frame in enumerate(picks):
            ax = fig.add_subplot(grid[row, col])
            image, _ = rasterise(meshes[frame], faces, colors, SIDE, center, cm_per_pixel, PIXELS)
            ax.imshow(image, interpolation="lanczos")
            ax.set_xticks([])
            ax.set_yticks([])
            for spine in ax.spines.values():
                spine.set_visible(False)
            record = frames.iloc[frame]
            detail = f"{record['vertex_error_cm']:.2f} cm" if row else f"{frame / fps:.2f} s"
            ax.set_title(
                f"{label} f{frame}: {detail}\nteeth inside: {int(record[teeth])}", fontsize=8
            )
    _curves(fig.add_subplot(grid[2, :]), frames, picks)
    fig.suptitle(
        f"{rig.name}: Blender soft body (top) mapped onto the rig (bottom), side view",
        fontsize=11,
    )
    fig.tight_layout()
    return save_and_close(fig, out_path, dpi=100, format="png")


def _curves(ax, frames: pd.DataFrame, picks: list[int]) -> None:
    ax.plot(frames["frame"], frames["vertex_error_cm"], label="rig vs simulation, RMS (cm)")
    ax.plot(
        frames["frame"],
        frames["guess_vertex_error_cm"],
        linestyle="--",
        label="guess before refinement (cm)",
    )
    ax.set_xlabel("frame")
    ax.set_ylabel("vertex error (cm)")
    height = ax.twinx()
    height.plot(frames["frame"], frames["simulation_height_cm"], color="0.6", linewidth=1)
    height.set_ylabel("simulated height (cm)", color="0.4")
    for frame in picks:
        ax.axvline(frame, color="0.85", linewidth=0.8, zorder=0)
    ax.legend(loc="upper right", fontsize=8)
