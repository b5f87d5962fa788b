"""Animated GIFs from a matplotlib figure redrawn frame by frame, written atomically."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from rigmap.store import atomic_file

GIF_COLORS = 64  # palette size of every frame (ours: small files, enough for line drawings)


def write_figure_gif(
    fig,
    draw: Callable[[int], None],
    indices: Iterable[int],
    out: str | os.PathLike,
    *,
    duration_ms: int,
) -> Path:
    """``draw(index)`` on ``fig`` for each index, each drawing one GIF frame of
    ``duration_ms``; the file is replaced whole or not at all."""
    from PIL import Image

    images = []
    for index in indices:
        draw(index)
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3].copy()).quantize(colors=GIF_COLORS))
    out = Path(out)
    with atomic_file(out, suffix=".gif") as temporary:
        images[0].save(
            temporary,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=duration_ms,
            loop=0,
        )
    return out
