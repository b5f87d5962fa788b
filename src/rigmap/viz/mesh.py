"""Shaded three-view pictures of a mesh rig (front, side, top), landmarks marked.

A small z-buffer rasteriser in numpy: orthographic cameras, Gouraud-shaded
Lambert lighting, per-face colours from the rig (``face_colors``) and 2x
supersampling. It needs nothing but numpy and matplotlib (for the layout), so
it runs in CI. The views are those of :mod:`rigmap.viz.skeleton`; rigs whose
``faces`` is not None are drawn with this module instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rigmap.rigs.mesh.geometry import vertex_normals
from rigmap.viz.atomic import save_and_close

DEFAULT_COLOR = (0.78, 0.74, 0.70)
BACKGROUND = (1.0, 1.0, 1.0)
LIGHT = np.array([-0.35, 0.55, 0.76])  # in camera space: from the upper left, towards the viewer
AMBIENT = 0.32
SUPERSAMPLE = 2


@dataclass(frozen=True)
class View:
    """An orthographic camera: rows of ``axes`` are screen right, screen up, towards viewer."""

    name: str
    axes: np.ndarray


VIEWS = (
    View("front", np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]])),
    # from the character's right side: it faces screen right
    View("side", np.array([[0, 0, 1.0], [0, 1.0, 0], [-1.0, 0, 0]])),
    # from above, its front towards the top of the picture
    View("top", np.array([[-1.0, 0, 0], [0, 0, 1.0], [0, 1.0, 0]])),
)


def render_mesh_views(
    rig,
    controls,
    out_path,
    *,
    title: str | None = None,
    pose_labels: list[str] | None = None,
    pixels: int = 300,
) -> Path:
    """Draw one row of front/side/top views per control vector into a PNG; return its path.

    ``controls`` is one control vector ``(C,)`` or several ``(P, C)`` (one row
    each). Landmarks (joints that are a subset of the mesh, e.g. the face's six
    points) are marked in red. The file is written atomically.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    Y = _check_mesh_controls(rig, controls, pose_labels)
    vertices = np.asarray(rig.mesh(Y))
    faces = np.asarray(rig.faces)
    colors = getattr(rig, "face_colors", None)
    colors = np.tile(DEFAULT_COLOR, (len(faces), 1)) if colors is None else np.asarray(colors)
    landmarks = None
    if rig.n_joints < vertices.shape[1]:
        landmarks = np.asarray(rig.evaluate(Y))

    # one scale (cm per pixel) for every panel, so poses and views compare
    extents = []
    for view in VIEWS:
        projected = vertices @ view.axes.T
        extents.append(np.ptp(projected[..., :2].reshape(-1, 2), axis=0))
    cm_per_pixel = 1.08 * max(float(np.max(extents)), 1e-6) / pixels

    n_rows = len(Y)
    fig, axes = plt.subplots(
        n_rows, len(VIEWS), figsize=(3.2 * len(VIEWS), 3.3 * n_rows), squeeze=False
    )
    for row in range(n_rows):
        for col, view in enumerate(VIEWS):
            ax = axes[row, col]
            center = _view_center(vertices @ view.axes.T)
            image, depth = rasterise(
                vertices[row], faces, colors, view, center, cm_per_pixel, pixels
            )
            ax.imshow(image, interpolation="lanczos")
            if landmarks is not None:
                _draw_landmarks(
                    ax,
                    landmarks[row],
                    rig.joint_names,
                    view,
                    center,
                    cm_per_pixel,
                    pixels,
                    depth,
                    label=(col == 0),
                )
            ax.set_xticks([])
            ax.set_yticks([])
            for spine in ax.spines.values():
                spine.set_visible(False)
            heading = view.name if pose_labels is None else f"{pose_labels[row]} — {view.name}"
            ax.set_title(heading, fontsize=9)
    fig.suptitle(
        title
        or f"{rig.name}: {rig.n_controls} controls, {vertices.shape[1]} vertices, "
        f"{rig.n_joints} joints (cm)",
        fontsize=11,
    )
    fig.tight_layout()
    return save_and_close(fig, out_path, dpi=110, format="png")


def _check_mesh_controls(rig, controls, pose_labels) -> np.ndarray:
    """``(P, C)`` control vectors of a mesh rig, one label per pose if labels are given."""
    if getattr(rig, "faces", None) is None or not hasattr(rig, "mesh"):
        raise ValueError(f"rig {rig.name!r} has no mesh (faces is None); draw it as a skeleton")
    Y = np.atleast_2d(np.asarray(controls, dtype=np.float64))
    if Y.ndim != 2 or Y.shape[1] != rig.n_controls:
        raise ValueError(
            f"render_mesh_views: rig {rig.name!r} expects controls of shape "
            f"({rig.n_controls},) or (P, {rig.n_controls}), got {np.shape(controls)}"
        )
    if pose_labels is not None and len(pose_labels) != len(Y):
        raise ValueError(f"{len(pose_labels)} pose labels for {len(Y)} poses")
    return Y


def rasterise(vertices, faces, colors, view: View, center, cm_per_pixel: float, pixels: int):
    """RGB image ``(pixels, pixels, 3)`` and depth buffer (cm, ``-inf`` where empty)."""
    size = pixels * SUPERSAMPLE
    camera = vertices @ view.axes.T
    normals = vertex_normals(vertices, faces) @ view.axes.T
    # screen coordinates: x right, y down, in supersampled pixels
    sx = (camera[:, 0] - center[0]) / cm_per_pixel * SUPERSAMPLE + size / 2
    sy = -(camera[:, 1] - center[1]) / cm_per_pixel * SUPERSAMPLE + size / 2
    sz = camera[:, 2]
    light = LIGHT / np.linalg.norm(LIGHT)
    facing = np.where(normals[:, 2:3] < 0, -normals, normals)  # back faces lit as seen
    intensity = AMBIENT + (1 - AMBIENT) * np.clip(facing @ light, 0.0, 1.0)

    tri_x, tri_y, tri_z = sx[faces], sy[faces], sz[faces]
    area = (tri_x[:, 1] - tri_x[:, 0]) * (tri_y[:, 2] - tri_y[:, 0]) - (
        tri_x[:, 2] - tri_x[:, 0]
    ) * (tri_y[:, 1] - tri_y[:, 0])
    x0 = np.floor(tri_x.min(1)).astype(int)
    y0 = np.floor(tri_y.min(1)).astype(int)
    side = np.maximum(
        np.ceil(tri_x.max(1)).astype(int) - x0, np.ceil(tri_y.max(1)).astype(int) - y0
    )
    side = np.maximum(side, 0) + 1
    drawable = np.abs(area) > 1e-12

    # every face tests the pixel centres of its bounding square; faces are batched by
    # square size (powers of two) so the work is a few large numpy operations
    pixel_ids, depths, shades, face_ids = [], [], [], []
    bucket = 1
    while True:
        members = np.flatnonzero(drawable & (side <= bucket) & (side > bucket // 2))
        if len(members):
            oy, ox = np.divmod(np.arange(bucket * bucket), bucket)
            px = x0[members, None] + ox[None, :]
            py = y0[members, None] + oy[None, :]
            cx, cy = px + 0.5, py + 0.5
            tx, ty, a = tri_x[members], tri_y[members], area[members, None]
            w0 = ((tx[:, 1:2] - cx) * (ty[:, 2:3] - cy) - (tx[:, 2:3] - cx) * (ty[:, 1:2] - cy)) / a
            w1 = ((tx[:, 2:3] - cx) * (ty[:, 0:1] - cy) - (tx[:, 0:1] - cx) * (ty[:, 2:3] - cy)) / a
            w2 = 1.0 - w0 - w1
            hit = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (px >= 0) & (px < size) & (py >= 0)
            hit &= py < size
            f_hit, k_hit = np.nonzero(hit)
            ids = members[f_hit]
            b0, b1, b2 = w0[f_hit, k_hit], w1[f_hit, k_hit], w2[f_hit, k_hit]
            pixel_ids.append(py[f_hit, k_hit] * size + px[f_hit, k_hit])
            depths.append(b0 * tri_z[ids, 0] + b1 * tri_z[ids, 1] + b2 * tri_z[ids, 2])
            shades.append(
                b0 * intensity[faces[ids, 0]]
                + b1 * intensity[faces[ids, 1]]
                + b2 * intensity[faces[ids, 2]]
            )
            face_ids.append(ids)
        if bucket >= side[drawable].max(initial=1):
            break
        bucket *= 2

    depth = np.full(size * size, -np.inf)
    image = np.tile(np.asarray(BACKGROUND, dtype=np.float64), (size * size, 1))
    if pixel_ids:
        pixel_ids, depths = np.concatenate(pixel_ids), np.concatenate(depths)
        shades, face_ids = np.concatenate(shades), np.concatenate(face_ids)
        # z-buffer: per pixel keep the candidate nearest the camera (largest depth)
        order = np.lexsort((depths, pixel_ids))
        last = np.r_[pixel_ids[order][1:] != pixel_ids[order][:-1], True]
        win = order[last]
        depth[pixel_ids[win]] = depths[win]
        image[pixel_ids[win]] = colors[face_ids[win]] * shades[win, None]
    depth = depth.reshape(size, size)
    image = image.reshape(size, size, 3)
    image = image.reshape(pixels, SUPERSAMPLE, pixels, SUPERSAMPLE, 3).mean(axis=(1, 3))
    depth = depth.reshape(pixels, SUPERSAMPLE, pixels, SUPERSAMPLE).max(axis=(1, 3))
    return np.clip(image, 0.0, 1.0), depth


def _view_center(projected: np.ndarray) -> np.ndarray:
    flat = projected.reshape(-1, 3)
    return 0.5 * (flat.min(axis=0) + flat.max(axis=0))


def _draw_landmarks(ax, points, names, view, center, cm_per_pixel, pixels, depth, *, label):
    camera = points @ view.axes.T
    px = (camera[:, 0] - center[0]) / cm_per_pixel + pixels / 2 - 0.5
    py = -(camera[:, 1] - center[1]) / cm_per_pixel + pixels / 2 - 0.5
    for x, y, z, name in zip(px, py, camera[:, 2], names, strict=True):
        i, j = int(np.clip(round(y), 0, pixels - 1)), int(np.clip(round(x), 0, pixels - 1))
        hidden = z < depth[i, j] - 0.3
        ax.plot(x, y, "o", ms=5, mfc="none" if hidden else "red", mec="red", mew=1.2)
        if label:
            left = x < pixels / 2 - 2  # label away from the middle so pairs do not overlap
            ax.annotate(
                name,
                (x, y),
                xytext=(-4 if left else 4, 3),
                textcoords="offset points",
                fontsize=6,
                color="darkred",
                ha="right" if left else "left",
            )
