"""A mapped clip as a .blend an animator opens: the rig with F-curves on its used controls.

``rigmap map`` gives every control of the rig per frame; animators key only the used
ones, so only those get F-curves (one per control, grouped by bone, on the control
bones' own channels and custom properties) and the rest keep their rest values.

- :func:`write_mapped_keys_blend` (what ``rigmap map`` writes, ``result.blend``): a copy of
  the rig's own file, its actions kept, with the mapping's *reduced* keys
  (:mod:`rigmap.map.key_reduction`) as a new action: the sparse keys an animator edits.
- :func:`write_mapped_blend`: every frame keyed (a bake), through
  :func:`rigmap.rigs.blender.export_blend`, the rig's file without its animation.

Both key in a Blender worker, put the frames where ``controls.parquet`` has them
(0, 1, …), set the scene's frame rate and write the file atomically.
"""

from __future__ import annotations

import os
from numbers import Real
from pathlib import Path

import numpy as np
import pandas as pd

from rigmap.animation.blend_corpus import action_payload
from rigmap.animation.keyframes import FCurve, Key
from rigmap.map.key_reduction import ReducedKeys
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


def mapped_action_curves(keys: ReducedKeys, *, first_frame: int = 0) -> dict[str, FCurve]:
    """The reduced keys as the curves of an action starting at ``first_frame``, each key
    with both Bézier handles (an end key's missing outer handle mirrors its inner one,
    so every handle pair is aligned and stays so when an animator drags one)."""
    shift = float(first_frame)
    curves = {}
    for name, curve in zip(keys.control_names, keys.curves, strict=True):
        placed = []
        for key in curve.keys:
            frame, value = float(key.frame), float(key.value)
            before, after = key.in_handle, key.out_handle
            if before is None and after is not None:
                before = (2 * frame - after[0], 2 * value - after[1])
            if after is None and before is not None:
                after = (2 * frame - before[0], 2 * value - before[1])

            def moved(handle):
                return None if handle is None else (handle[0] + shift, handle[1])

            placed.append(Key(frame + shift, value, key.interpolation, moved(before), moved(after)))
        curves[name] = FCurve(placed, control=name)
    return curves


def write_mapped_keys_blend(
    rig,
    keys: ReducedKeys,
    fps: float,
    path: str | os.PathLike,
    *,
    first_frame: int = 0,
    action_name: str | None = None,
) -> Path:
    """A copy of the rig's own .blend with the mapping's sparse keys as a new action.

    What an animator gets back from ``rigmap map``: their file as it was (every action it
    holds is kept; the one the armature played gets a fake user so it survives the save)
    plus an action named ``action_name`` (default ``<rig>_mapped``) assigned to the
    armature, keyed on the controls the mapping keyed (the rig's used controls: for
    ``rig=blend_file`` the ones the file's actions key) with aligned Bézier handles, and
    the scene's frame range and rate set to the clip's. The rig's file is only read;
    ``path`` (never the rig's own file) appears whole or not at all.
    """
    rig = blender_rig(rig)
    path = Path(path).expanduser().resolve()
    if path.suffix != ".blend":
        raise ValueError(f"mapped .blend path must end in .blend, got {path.name!r}")
    if path == Path(rig.path).resolve():
        raise ValueError(f"{path}: the mapped keys go into a copy, not the rig's own file")
    if isinstance(fps, bool) or not isinstance(fps, Real) or not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be a positive number of frames per second, got {fps!r}")
    unknown = [n for n in keys.control_names if n not in rig.controls]
    if unknown:
        raise ValueError(f"keys name controls {unknown[:6]} that rig {rig.name!r} does not have")
    curves = mapped_action_curves(keys, first_frame=first_frame)
    action = action_payload(
        action_name or f"{rig.name.replace(':', '_')}_mapped",
        int(first_frame),
        int(first_frame) + keys.frames - 1,
        curves,
    )
    action["handle_type"] = "ALIGNED"
    options = {**rig.session_options, "prune": False, "keep_animation": True}
    with atomic_file(path, suffix=".blend") as temporary, rig.make_pool(options, workers=1) as pool:
        pool.call(
            "write_actions",
            {
                "clips": [action],
                "fps": float(fps),
                "out_path": str(temporary),
                "scene_range": True,
            },
        )
    return path
