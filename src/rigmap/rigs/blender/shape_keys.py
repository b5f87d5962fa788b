"""A mesh rig's animation as Blender shape keys with an action, and reading it back.

For a built-in mesh rig such as the ARKit face (:mod:`rigmap.rigs.characters.arkit_face`)
an animator wants the face itself in Blender, not an armature: ``export_shape_key_blend``
writes the rig's rest mesh with one shape key per animated control and an action keying
the keys' weights frame by frame, so the synthesised animation plays when the file is
opened. ``read_shape_key_blend`` plays such a file in a worker and returns the weights,
``read_shape_key_mesh`` the evaluated vertices at one frame — the round trip that proves
the file is right.

Blender runs in a worker process (:mod:`.in_blender.shape_keys` does the bpy work); only
numbers cross: vertices in Blender's metres and axes, weights, frames.
"""

from __future__ import annotations

from numbers import Real
from pathlib import Path

import numpy as np

from rigmap.errors import RigmapError
from rigmap.rigs.blender.cache import cache_dir
from rigmap.rigs.blender.environment import find_blender
from rigmap.rigs.blender.export import FRAME_COLUMN, _control_table

#: rigmap's axes (Y up, the face looking along +Z, +X its left) -> Blender's (Z up, the
#: face looking along -Y): a -90 degree turn about X, as for the Blender rigs (rig_session)
RIGMAP_TO_BLENDER_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
#: rigmap's lengths are centimetres, Blender's metres
CM_PER_METRE = 100.0
#: Blender's own limit on a shape key's slider range (so on its weight)
BLENDER_SLIDER_LIMIT = 10.0
#: seconds one worker request may take (ours: a long clip on the 52-key face takes seconds)
WORKER_TIMEOUT_S = 600.0


class ShapeKeyExportError(RigmapError, ValueError):
    """The rig, the table or the path cannot make a shape-key .blend; the message says which."""


def export_shape_key_blend(
    rig, controls, out_path, *, fps: float, action_name: str | None = None
) -> Path:
    """Write ``rig``'s mesh with ``controls`` as animated shape keys into a new .blend.

    ``controls`` is a table with a ``frame`` column and one column per control, named as
    the rig names them; controls without a column get no shape key. Each exported
    control's key is the rig's mesh with that control at its upper soft bound (1 for the
    ARKit face) and every other control at its default; its weight at a frame is
    ``(value - default) / (upper - default)``, which for the ARKit face (defaults 0,
    uppers 1) is the control value itself. The mesh is placed as the rig gives it
    (relative to its centre of gravity, at the world origin), in metres, turned upright
    into Blender's Z-up world (rigmap's +Y up becomes +Z, its +Z forward becomes -Y, so
    Blender's front view looks the face in the eyes). ``fps`` may be fractional (29.97 is
    stored as 30 / 1.001); the scene's range covers the table's frames. The file is
    written to a temporary name in ``out_path``'s folder and renamed: a failure leaves no
    half-written file.

    Blender's shape keys add linearly (rest + sum of weight x delta); the rig's own
    deformation may not (the face's sliders clamp, combination correctives switch on
    when shapes combine, the jaw is skinned, so its rotation is not a straight line).
    The .blend's mesh therefore equals the rig's exactly with one shape on at a time;
    with several, it is their linear sum. The key weights always equal the controls.
    """
    faces = getattr(rig, "faces", None)
    if not callable(getattr(rig, "mesh", None)) or faces is None:
        raise ShapeKeyExportError(
            f"rig {getattr(rig, 'name', rig)!r} has no mesh (mesh() and faces): shape keys "
            "need one; key an armature rig's controls with export_blend"
        )
    try:
        frames, values, names = _control_table(rig, controls)
    except ValueError as error:  # the same table contract as export_blend, our error class
        raise ShapeKeyExportError(str(error)) from None
    out_path = Path(out_path).expanduser().resolve()
    if out_path.suffix != ".blend":
        raise ShapeKeyExportError(f"out_path must end in .blend, got {out_path.name!r}")
    if not (isinstance(fps, Real) and np.isfinite(fps) and fps > 0):
        raise ShapeKeyExportError(
            f"fps must be a positive number of frames per second, got {fps!r}"
        )
    columns = np.array([rig.controls.index(name) for name in names])
    defaults = rig.controls.defaults[columns]
    full_on = rig.controls.upper[columns]
    flat = np.flatnonzero(full_on == defaults)
    if len(flat):
        raise ShapeKeyExportError(
            f"control {names[flat[0]]!r} has its default at its upper bound: no shape to key"
        )
    weights = (values - defaults) / (full_on - defaults)
    _check_weights(weights, names)

    rest_controls = rig.default_controls(1)
    single_controls = rig.default_controls(len(names))
    single_controls[np.arange(len(names)), columns] = full_on
    rest = to_blender(np.asarray(rig.mesh(rest_controls))[0])
    shapes = to_blender(np.asarray(rig.mesh(single_controls)))
    with _worker_pool() as pool:
        pool.call(
            "write_shape_keys",
            {
                "object": rig.name,
                "names": names,
                "action": action_name or f"{rig.name}_rigmap",
                "fps": float(fps),
                "out_path": str(out_path),
            },
            {
                "rest": rest,
                "triangles": np.asarray(faces, dtype=np.int64),
                "shapes": shapes,
                "frames": frames,
                "weights": weights,
            },
        )
    return out_path


def read_shape_key_blend(path):
    """Each shape key's weight, as Blender plays the file, at every whole frame of its
    scene range: a table with ``frame`` and one column per shape key (the Basis aside);
    ``attrs`` hold the scene's ``fps`` and the mesh ``object``'s name.

    The file must hold one mesh object with shape keys (what ``export_shape_key_blend``
    writes); for the ARKit face the weights are the control values.
    """
    import pandas as pd

    info, out = _read(path, vertices_at=None)
    table = pd.DataFrame(out["weights"], columns=info["names"])
    table.insert(0, FRAME_COLUMN, out["frames"])
    table.attrs.update(fps=info["fps"], object=info["object"])
    return table


def read_shape_key_mesh(path, frame: float) -> np.ndarray:
    """The mesh Blender evaluates at ``frame``: ``(V, 3)`` vertices in rigmap's cm and axes,
    comparable with the rig's ``mesh``."""
    _, out = _read(path, vertices_at=float(frame))
    return from_blender(out["vertices"])


def to_blender(vertices: np.ndarray) -> np.ndarray:
    """rigmap vertices (cm, Y up) -> Blender's (metres, Z up); any leading batch axes."""
    return np.asarray(vertices, dtype=np.float64) @ RIGMAP_TO_BLENDER_AXES.T / CM_PER_METRE


def from_blender(vertices: np.ndarray) -> np.ndarray:
    """Blender vertices (metres, Z up) -> rigmap's (cm, Y up)."""
    return np.asarray(vertices, dtype=np.float64) @ RIGMAP_TO_BLENDER_AXES * CM_PER_METRE


def _check_weights(weights: np.ndarray, names: list[str]) -> None:
    outside = np.argwhere(np.abs(weights) > BLENDER_SLIDER_LIMIT)
    if len(outside):
        row, column = outside[0]
        raise ShapeKeyExportError(
            f"controls table row {row}, column {names[column]!r}: weight "
            f"{weights[row, column]:.6g} is outside Blender's shape-key range "
            f"[-{BLENDER_SLIDER_LIMIT:g}, {BLENDER_SLIDER_LIMIT:g}]"
        )


def _read(path, vertices_at: float | None):
    path = Path(path).expanduser().resolve()
    if not path.is_file():
        raise FileNotFoundError(f"no .blend file at {path}")
    with _worker_pool() as pool:
        return pool.call("read_shape_keys", {"path": str(path), "vertices_at": vertices_at})


def _worker_pool():
    from rigmap.rigs.blender.pool import WorkerPool

    command = find_blender(None)
    return WorkerPool(
        lambda _slot: command.argv(),
        workers=1,
        timeout=WORKER_TIMEOUT_S,
        log_dir=cache_dir() / "logs",
    )
