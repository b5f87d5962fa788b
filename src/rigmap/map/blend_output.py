"""A mapped clip as a .blend an animator opens: the rig with F-curves on its used controls.

``rigmap map`` gives every control of the rig per frame; animators key only the used
ones, so only those get F-curves (one per control, grouped by bone, on the control
bones' own channels and custom properties) and the rest keep their rest values. The
keying itself is :func:`rigmap.rigs.blender.export_blend` (a Blender worker); this
module checks the mapped array, puts the frames where ``controls.parquet`` has them
(0, 1, …), sets the scene's frame rate and writes the file atomically.
"""

from __future__ import annotations

import os
from numbers import Real
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.rigs.blender.export import FRAME_COLUMN, export_blend
from rigmap.rigs.blender.lookup import blender_rig
from rigmap.store import atomic_file


def mapped_controls_table(rig, controls: np.ndarray, *, first_frame: int = 0) -> pd.DataFrame:
    """``frame`` plus one column per used control, from ``(F, C)`` values of every control."""
    values = np.asarray(controls, dtype=np.float64)
    n_controls = len(rig.control_names)
    if values.ndim != 2 or values.shape[1] != n_controls:
        raise ValueError(
            f"mapped controls must be (frames, {n_controls}) for rig {rig.name!r} (every "
            f"control), got shape {values.shape}"
        )
    if len(values) == 0:
        raise ValueError(f"mapped controls for rig {rig.name!r} have no frames")
    bad = np.argwhere(~np.isfinite(values))
    if len(bad):
        row, column = bad[0]
        raise ValueError(
            f"mapped controls have NaN or infinity (first at frame {row}, control "
            f"{rig.control_names[column]!r})"
        )
    used = rig.controls.used_indices
    table = pd.DataFrame(values[:, used], columns=list(rig.used_controls))
    table.insert(0, FRAME_COLUMN, np.arange(len(values)) + int(first_frame))
    return table


def write_mapped_blend(
    rig, controls: np.ndarray, fps: float, path: str | os.PathLike, *, first_frame: int = 0
) -> Path:
    """Write ``controls`` (``(F, C)``, every control) keyed on ``rig``'s used controls.

    Frame ``k`` of the array is keyed at scene frame ``first_frame + k``; the scene
    plays at ``fps``. The file appears whole or not at all; returns its path.
    """
    rig = blender_rig(rig)
    path = Path(path)
    if path.suffix != ".blend":
        raise ValueError(f"mapped .blend path must end in .blend, got {path.name!r}")
    if isinstance(fps, bool) or not isinstance(fps, Real) or not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a positive number of frames per second, got {fps!r}")
    table = mapped_controls_table(rig, controls, first_frame=first_frame)
    with atomic_file(path, suffix=".blend") as temporary:
        export_blend(rig, table, temporary, action_name=f"{rig.name}_mapped", fps=float(fps))
    return path
