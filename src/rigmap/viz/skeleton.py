"""Skeleton drawings: joints as dots, bones as lines, from front, side and top.

Views follow the rigs' convention (Y up, the character faces +Z, +X is its
left): ``front`` looks at the character's face (its left on the viewer's
right), ``side`` looks from its right side (facing right, +Z to the right),
``top`` looks down (forward up the page, its left on the viewer's left).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rigmap.viz.atomic import save_and_close

# (horizontal axis, vertical axis, horizontal sign) per view
VIEWS: dict[str, tuple[int, int, float]] = {
    "front": (0, 1, 1.0),
    "side": (2, 1, 1.0),
    "top": (0, 2, -1.0),
}
VIEW_AXIS_LABELS = {
    "front": ("x (cm)", "y (cm)"),
    "side": ("z (cm)", "y (cm)"),
    "top": ("x (cm)", "z (cm)"),
}


def project(positions: np.ndarray, view: str) -> tuple[np.ndarray, np.ndarray]:
    """2D coordinates of ``(J, 3)`` positions in a named view."""
    if view not in VIEWS:
        raise ValueError(f"view must be one of {sorted(VIEWS)}, got {view!r}")
    h, v, sign = VIEWS[view]
    return sign * positions[:, h], positions[:, v]


def side_colors(joint_names: list[str]) -> list[str]:
    """Left limbs blue, right limbs red, the rest dark grey — as DCCs colour controls."""
    colors = []
    for name in joint_names:
        if name.endswith("_l") or "_l_" in name:
            colors.append("tab:blue")
        elif name.endswith("_r") or "_r_" in name:
            colors.append("tab:red")
        else:
            colors.append("0.2")
    return colors


def draw_skeleton(
    ax,
    positions: np.ndarray,
    parents: np.ndarray,
    view: str = "side",
    *,
    joint_names: list[str] | None = None,
    color: str | None = None,
    alpha: float = 1.0,
    joint_size: float = 6.0,
    linewidth: float = 1.6,
) -> None:
    """Draw one skeleton (``(J, 3)`` world positions) into a matplotlib axis."""
    x, y = project(np.asarray(positions), view)
    colors = side_colors(joint_names) if joint_names and color is None else None
    for j, p in enumerate(parents):
        if p < 0:
            continue
        c = color or (colors[j] if colors else "0.2")
        ax.plot(
            [x[p], x[j]], [y[p], y[j]], color=c, lw=linewidth, alpha=alpha, solid_capstyle="round"
        )
    ax.scatter(
        x, y, s=joint_size, c=color or (colors or "0.1"), alpha=alpha, zorder=3, linewidths=0
    )


def render_skeleton_views(
    rig,
    controls: np.ndarray,
    out_path: str | Path,
    *,
    title: str | None = None,
    ghost_rest: bool = True,
) -> Path:
    """A PNG with the posed skeleton from front, side and top (world space, cm)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pose = rig.pose(np.asarray(controls, dtype=np.float64)[None])
    world = pose.positions[0] + pose.cog[0]
    rest = rig.rest_positions if ghost_rest and hasattr(rig, "rest_positions") else None
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.4))
    for ax, view in zip(axes, VIEWS, strict=True):
        if rest is not None:
            draw_skeleton(ax, rest, rig.parents, view, color="0.75", alpha=0.7, joint_size=3)
        draw_skeleton(ax, world, rig.parents, view, joint_names=rig.joint_names)
        # ground plane (y = 0) in the views that show height
        if view != "top":
            ax.axhline(0.0, color="0.6", lw=0.8, ls="--")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(view)
        ax.set_xlabel(VIEW_AXIS_LABELS[view][0])
        ax.set_ylabel(VIEW_AXIS_LABELS[view][1])
        ax.grid(alpha=0.2)
    fig.suptitle(title or f"{rig.name}: {rig.n_joints} joints, {rig.n_controls} controls")
    fig.tight_layout()
    return save_and_close(fig, out_path, dpi=110)
