"""Control curves to an animator's .blend: keyframes on the rig's controls, and back.

``export_blend`` keys a table of control values (one column per control, plus
``frame``) onto the rig's own control channels as F-curves and saves the rig's
file with that action as a new .blend. ``read_blend_animation`` opens such a
file in a worker and plays it: the keyed values and the joint positions they
produce, frame by frame — the round trip that proves the file is right.
"""

from __future__ import annotations

from numbers import Real
from pathlib import Path

import numpy as np

from rigmap.rigs.base import Pose
from rigmap.rigs.blender.lookup import blender_rig
from rigmap.rigs.blender.rig import BlenderRig

FRAME_COLUMN = "frame"


def _control_table(rig: BlenderRig, controls) -> tuple[np.ndarray, np.ndarray, list[str]]:
    import pandas as pd

    if not isinstance(controls, pd.DataFrame):
        raise TypeError(f"controls must be a pandas DataFrame, got {type(controls).__name__}")
    columns = [str(c) for c in controls.columns]
    if FRAME_COLUMN not in columns:
        raise ValueError(
            f"controls table has no {FRAME_COLUMN!r} column; columns start {columns[:8]}"
        )
    names = [c for c in columns if c != FRAME_COLUMN]
    if not names:
        raise ValueError(f"controls table has only a {FRAME_COLUMN!r} column: no control to key")
    unknown = [n for n in names if n not in rig.controls]
    if unknown:
        raise ValueError(
            f"controls table columns {unknown[:10]} are not controls of rig {rig.name!r} "
            f"({len(unknown)} unknown; controls look like {rig.control_names[:4]})"
        )
    if len(controls) == 0:
        raise ValueError("controls table has no rows")
    try:
        frames = controls[FRAME_COLUMN].to_numpy(dtype=np.float64)
        values = controls[names].to_numpy(dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"controls table must hold numbers only: {error}") from None
    bad = np.argwhere(~np.isfinite(np.column_stack([frames, values])))
    if len(bad):
        row, col = bad[0]
        column = ([FRAME_COLUMN, *names])[col]
        raise ValueError(
            f"controls table has NaN or infinity (first at row {row}, column {column!r})"
        )
    if len(np.unique(frames)) != len(frames):
        raise ValueError(f"controls table repeats frames in {FRAME_COLUMN!r}: one row per frame")
    return frames, values, names


CLIP_COLUMN = "clip"


def clip_rows(controls, clip: str | None = None):
    """The rows of one clip of a table with a ``clip`` column, without that column.

    rigmap's own control tables (MLflow's ``predicted_controls.parquet``, the corpus) carry
    ``clip`` beside ``frame``; a table of one clip needs no choice, several need ``clip``.
    A table without the column is returned as it is (``clip`` must then be ``None``).
    """
    if CLIP_COLUMN not in controls.columns:
        if clip is not None:
            raise ValueError(f"controls table has no {CLIP_COLUMN!r} column to pick {clip!r} from")
        return controls
    clips = list(dict.fromkeys(str(c) for c in controls[CLIP_COLUMN]))
    if clip is None:
        if len(clips) != 1:
            raise ValueError(
                f"controls table holds {len(clips)} clips {clips[:6]}: pick one with --clip NAME"
            )
        clip = clips[0]
    if clip not in clips:
        raise ValueError(f"controls table has no clip {clip!r}; clips: {clips[:10]}")
    rows = controls[controls[CLIP_COLUMN].astype(str) == clip]
    return rows.drop(columns=[CLIP_COLUMN]).reset_index(drop=True)


def export_blend(
    rig_config_or_rig,
    controls,
    out_path,
    *,
    action_name: str | None = None,
    fps: float | None = None,
) -> Path:
    """Write ``controls`` as keyframes on the rig into a new .blend at ``out_path``.

    Translations are in the rig's length unit (cm), rotations in radians, as
    everywhere in rigmap; they are converted to Blender's metres when keyed.
    Controls without a column keep their rest values and get no keys. ``fps``
    sets the scene's frame rate (``None`` keeps the rig file's).
    """
    rig = blender_rig(rig_config_or_rig)
    frames, values, names = _control_table(rig, controls)
    out_path = Path(out_path).expanduser().resolve()
    if out_path.suffix != ".blend":
        raise ValueError(f"out_path must end in .blend, got {out_path.name!r}")
    if fps is not None and not (isinstance(fps, Real) and np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number of frames per second, got {fps!r}")
    options = {**rig.session_options, "prune": False, "keep_animation": False}
    with rig.make_pool(options, workers=1) as pool:
        pool.call(
            "export",
            {
                "out_path": str(out_path),
                "names": names,
                "action": action_name or f"{rig.name}_rigmap",
                "fps": None if fps is None else float(fps),
            },
            {"frames": frames, "values": values},
        )
    return out_path


def read_blend_animation(rig_config_or_rig, path, frames=None):
    """Play the keyed file ``path`` on the rig: ``(controls DataFrame, Pose)`` per frame.

    ``frames`` defaults to the file's scene frame range. The controls table
    has one column per rig control plus ``frame``.
    """
    import pandas as pd

    rig = blender_rig(rig_config_or_rig)
    path = Path(path).expanduser().resolve()
    if not path.is_file():
        raise FileNotFoundError(f"no .blend file at {path}")
    options = {**rig.session_options, "path": str(path), "prune": False, "keep_animation": True}
    arrays = {} if frames is None else {"frames": np.asarray(frames, dtype=np.float64)}
    with rig.make_pool(options, workers=1) as pool:
        _, out = pool.call("play", {}, arrays)
    table = pd.DataFrame(out["controls"], columns=rig.control_names)
    table.insert(0, FRAME_COLUMN, out["frames"])
    return table, Pose(out["positions"], out["cog"], out["cog_rotation"])
