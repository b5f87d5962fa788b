"""The paper's Fig. 4 for any rig: random supersamples of each strategy, drawn as poses.

One row per sampling strategy (Table 2 order), a few randomly chosen samples per
row, every pose drawn at the same scale. A person sees at a glance why uniform
samples look extreme (every control anywhere in its range, regardless of the
others) while PCA + Gaussian samples look like the animators' poses (§6.2).

Articulated rigs are drawn as skeletons (side view), mesh rigs as small shaded
thumbnails (:func:`rigmap.viz.mesh.rasterise`). The COG's heading is turned to
face the same way in every panel, so the pose, not where the character looks,
is what differs; heights stay, so feet through the floor show.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigmap.catalog import default_catalogue
from rigmap.viz.atomic import save_and_close
from rigmap.viz.mesh import DEFAULT_COLOR, rasterise
from rigmap.viz.mesh import VIEWS as MESH_VIEWS
from rigmap.viz.skeleton import draw_skeleton, project

THUMBNAIL_PIXELS = 150
PANEL_INCHES = 1.75  # height of one pose's panel
LABEL_INCHES = 2.0  # left margin for the row titles
TITLE_INCHES = 0.6


@dataclass(frozen=True)
class PoseRow:
    """The poses drawn in one row of the figure."""

    strategy: str
    title: str
    note: str
    """Second line of the row's title: how many samples, how many clamped."""
    indices: np.ndarray
    """Which samples (or corpus frames) of the strategy were drawn."""
    controls: np.ndarray
    """``(k, C_used)`` used-control values of the drawn poses."""
    positions: np.ndarray
    """``(k, J, 3)`` joint positions relative to the COG (cm)."""
    cog: np.ndarray
    cog_rotation: np.ndarray


@dataclass(frozen=True)
class SampleFigure:
    """The written figure and what is in it, row by row."""

    path: Path
    view: str
    rows: list[PoseRow]


def sample_rows(
    rig,
    samples: Mapping[str, Mapping],
    corpus_controls,
    *,
    per_row: int = 6,
    rng: np.random.Generator,
) -> list[PoseRow]:
    """Pick ``per_row`` random poses of the corpus and of every strategy in ``samples``.

    ``samples`` maps a strategy name to its ``load_samples`` dict or open
    ``np.load`` file (then only the drawn rows stay in memory). The first row
    is the corpus (the training data of strategy ``none``, which adds nothing);
    a ``none`` entry, if given, must be empty. The corpus row is posed here; the
    strategies' rows use the positions stored with their samples.
    """
    corpus = np.asarray(corpus_controls, dtype=np.float64)
    n_used = len(rig.used_controls)
    if corpus.ndim != 2 or corpus.shape[1] != n_used or len(corpus) == 0:
        raise ValueError(
            f"sample_rows: corpus controls must have shape (frames >= 1, {n_used}) for rig "
            f"{rig.name!r}, got {corpus.shape}"
        )
    if per_row < 1:
        raise ValueError(f"sample_rows: per_row must be >= 1, got {per_row}")
    chosen = _pick(len(corpus), per_row, rng)
    pose = rig.pose(rig.expand_used(corpus[chosen]))
    rows = [
        PoseRow(
            "none",
            f"corpus ({default_catalogue().sampler('none').label})",
            f"{len(corpus)} animator frames",
            chosen,
            corpus[chosen],
            *(np.asarray(part, dtype=np.float64) for part in pose),
        )
    ]
    for name, data in samples.items():
        controls = data["controls"]
        n = len(controls)
        if name == "none":
            if n:
                raise ValueError(f"sample_rows: strategy 'none' should add no samples, has {n}")
            continue
        if n == 0:
            raise ValueError(f"sample_rows: strategy {name!r} has no samples to draw")
        chosen = _pick(n, per_row, rng)
        drawn = {"controls": controls[chosen]}
        for key in ("positions", "cog", "cog_rotation"):
            drawn[key] = np.asarray(data[key][chosen], dtype=np.float64)
        if drawn["positions"].shape[1:] != (rig.n_joints, 3):
            raise ValueError(
                f"sample_rows: {name!r} positions have shape (n, "
                f"{', '.join(map(str, drawn['positions'].shape[1:]))}), expected "
                f"(n, {rig.n_joints}, 3) for rig {rig.name!r}"
            )
        clamped = int(data["n_clamped"]) / controls.size
        rows.append(
            PoseRow(
                name,
                default_catalogue().sampler(name).label,  # its own name if uncatalogued
                f"{n} samples,\n{clamped:.1%} of values clamped",
                chosen,
                **drawn,
            )
        )
    return rows


def draw_sample_figure(
    rig,
    rows: list[PoseRow],
    out_path,
    *,
    view: str | None = None,
    title: str | None = None,
) -> SampleFigure:
    """Draw ``rows`` (from :func:`sample_rows`) into a PNG, atomically; return what was drawn.

    ``view``: ``front``, ``side`` (the default: limbs, spine and tail move in the
    character's sagittal plane) or ``top``.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    if not rows:
        raise ValueError("draw_sample_figure: no rows to draw")
    mesh = getattr(rig, "faces", None) is not None and hasattr(rig, "mesh")
    view = view or "side"
    if view not in {v.name for v in MESH_VIEWS}:
        raise ValueError(f"draw_sample_figure: view must be front, side or top, got {view!r}")
    per_row = max(len(row.indices) for row in rows)
    panel_width = PANEL_INCHES
    if not mesh:
        skeletons, h_limits, v_limits = _skeleton_frames(rows, view)
        # panels shaped like the poses: a tall biped gets narrow panels, a dog wide ones
        aspect = (h_limits[1] - h_limits[0]) / (v_limits[1] - v_limits[0])
        panel_width = PANEL_INCHES * float(np.clip(aspect, 0.5, 1.6))
    fig, axes = plt.subplots(
        len(rows),
        per_row,
        figsize=(panel_width * per_row + LABEL_INCHES, PANEL_INCHES * len(rows) + TITLE_INCHES),
        squeeze=False,
    )
    if mesh:
        _draw_meshes(rig, rows, axes, view)
    else:
        _draw_skeletons(rig, rows, axes, view, skeletons, h_limits, v_limits)
    for r, row in enumerate(rows):
        for c in range(len(row.indices), per_row):
            axes[r, c].set_visible(False)
        first = axes[r, 0]
        first.text(
            -0.08,
            0.5,
            f"{row.title}\n{row.note}",
            transform=first.transAxes,
            ha="right",
            va="center",
            fontsize=9,
        )
    what = "shaded mesh" if mesh else "skeleton"
    fig.suptitle(
        title
        or f"{rig.name}: {per_row} random samples per strategy\n"
        f"({what}, {view} view, heading turned to face the same way)",
        fontsize=10,
    )
    fig.subplots_adjust(left=LABEL_INCHES / fig.get_figwidth(), right=0.99, bottom=0.01)
    fig.subplots_adjust(top=1 - TITLE_INCHES / fig.get_figheight())
    fig.subplots_adjust(wspace=0.04, hspace=0.08)
    path = save_and_close(fig, out_path, dpi=100, format="png")
    return SampleFigure(Path(path), view, rows)


def facing_forward(points: np.ndarray, cog_rotation: np.ndarray) -> np.ndarray:
    """``(k, P, 3)`` COG-relative points turned about the vertical so each COG faces +Z."""
    forward = cog_rotation[:, :, 2]  # where the COG's local +Z (the character's front) points
    heading = np.arctan2(forward[:, 0], forward[:, 2])
    cos, sin = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return np.stack([cos * x - sin * z, y, sin * x + cos * z], axis=-1)


def _skeleton_frames(rows: list[PoseRow], view: str):
    """Each row's poses as drawn (heading removed, height kept) and the shared axis limits."""
    poses = []
    for row in rows:
        upright = facing_forward(row.positions, row.cog_rotation)
        upright[..., 1] += row.cog[:, None, 1]  # keep the height above the ground
        poses.append(upright)
    h = np.concatenate([project(p.reshape(-1, 3), view)[0] for p in poses])
    v = np.concatenate([project(p.reshape(-1, 3), view)[1] for p in poses])
    if view != "top":
        v = np.append(v, 0.0)  # the ground is always in the picture
    pad = 0.04 * max(np.ptp(h), np.ptp(v), 1e-6)
    return poses, (h.min() - pad, h.max() + pad), (v.min() - pad, v.max() + pad)


def _draw_skeletons(rig, rows: list[PoseRow], axes, view: str, poses, h_limits, v_limits):
    for r, (row, upright) in enumerate(zip(rows, poses, strict=True)):
        for c, positions in enumerate(upright):
            ax = axes[r, c]
            if view != "top":
                ax.axhline(0.0, color="0.7", lw=0.6, ls="--", zorder=0)
            draw_skeleton(
                ax,
                positions,
                rig.parents,
                view,
                joint_names=rig.joint_names,
                joint_size=1.5,
                linewidth=0.9,
            )
            ax.set_xlim(*h_limits)
            ax.set_ylim(*v_limits)
            ax.set_aspect("equal", adjustable="box")
            _bare(ax, background=(0.97, 0.97, 0.97) if row.strategy == "none" else None)


def _draw_meshes(rig, rows: list[PoseRow], axes, view_name: str) -> None:
    view = next(v for v in MESH_VIEWS if v.name == view_name)
    faces = np.asarray(rig.faces)
    colors = getattr(rig, "face_colors", None)
    colors = np.tile(DEFAULT_COLOR, (len(faces), 1)) if colors is None else np.asarray(colors)
    meshes = []
    for row in rows:
        vertices = np.asarray(rig.mesh(rig.expand_used(row.controls)), dtype=np.float64)
        meshes.append(facing_forward(vertices, row.cog_rotation))
    # one scale and centre for every thumbnail, taken from the corpus row, so an extreme
    # sample that leaves the frame shows as what it is rather than shrinking the others
    reference = (meshes[0] @ view.axes.T).reshape(-1, 3)
    center = 0.5 * (reference.min(axis=0) + reference.max(axis=0))
    extent = float(np.ptp(reference[:, :2], axis=0).max())
    cm_per_pixel = 1.25 * max(extent, 1e-6) / THUMBNAIL_PIXELS
    for r, (row, vertices) in enumerate(zip(rows, meshes, strict=True)):
        for c, posed in enumerate(vertices):
            image, _ = rasterise(posed, faces, colors, view, center, cm_per_pixel, THUMBNAIL_PIXELS)
            ax = axes[r, c]
            ax.imshow(image, interpolation="lanczos")
            _bare(ax, background=None)
            if row.strategy == "none":
                for spine in ax.spines.values():
                    spine.set_visible(True)
                    spine.set_color("0.8")


def _bare(ax, *, background) -> None:
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_visible(False)
    if background is not None:
        ax.set_facecolor(background)


def _pick(n: int, k: int, rng: np.random.Generator) -> np.ndarray:
    return np.sort(rng.choice(n, size=min(k, n), replace=False))
