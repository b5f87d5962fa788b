"""Edit authoring (§5): a bone-length-preserving IK, minimal-rotation angles, edit signals.

How an artist makes the examples the GPs learn from (skeleton mode):

1. :func:`bone_length_ik` — the artist drags joints as if they were independent (each
   joint's target is its position plus its painted weight times the drag); the system
   finds the joint positions closest to the targets that keep every bone's length,
   ``min Σ_i |p_i − p*_i|²  s.t.  |p_i − p_parent(i)|² = d_i²``, with end effectors
   pinned by extra constraints ``p_k = c_k``. Solved as §5 says: Newton–Raphson on the
   Lagrangian, whose Hessian ``2I + Σ_b 2λ_b (e_i − e_j)(e_i − e_j)ᵀ ⊗ I₃`` is sparse;
   each step solves the sparse KKT system (scipy's ``spsolve``). A bone of zero length
   (the CMU files' ``LHipJoint``) is the linear constraint ``p_i = p_parent`` (its
   quadratic form has a zero gradient at the solution).
2. :func:`minimal_rotation_pose` — joint angles from the new positions: top-down, each
   joint keeps its old local rotation except for the smallest rotation that turns its
   bone onto the new direction ("the minimum rotation required for each bone to align
   with the new joint positions", Fig 5), so the twist about the bone is kept. A joint
   with several children (the hips, the chest) gets the rotation that best aligns all of
   them, weighted by bone length (Kabsch; ours: §5 does not say).
3. :func:`offset_signal` and :func:`timing_signal` — the offset ``d(t)`` (``y(t) = d(t) +
   x(t)``) and the timing ``k(t)`` (``y(t) = d(t) + x(t + k(t))``) of an edit at frame
   ``t̂``, blended linearly in over the ``blend`` frames before and out over the ``blend``
   after (§5: "smoothly blend in the difference … using a linear blend");
   :func:`apply_pose_edit` and :func:`apply_timing_edit` apply them to a target track.
4. :func:`pin_feet` — §7.3's automated clean-up: the source's foot contacts pinned on
   an edited track with the same IK.

The IK edits the pose channels only (root height and tilt and the joints' exponential
maps); where the root stands on the ground stays the source's (the step channels are
per-frame differentials: moving one frame's root would move every later frame). The
tolerances and the iteration cap are ours.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.sparse import coo_matrix, csc_matrix
from scipy.sparse.linalg import spsolve
from scipy.spatial.transform import Rotation

from rigmap.edits.representation import TargetError, TargetTrack
from rigmap.edits.skeleton_mode import Skeleton
from rigmap.regression.placement import turn_matrix

TOLERANCE = 1e-10  # largest |bone length² − d²| and pin error at convergence (ours)
MAX_ITERATIONS = 50  # ours


class AuthoringError(TargetError):
    """An IK request or an edit signal that cannot be made; names the joint or frame."""


# --- 1. bone-length-preserving IK ------------------------------------------------------------
def bone_length_ik(
    positions: np.ndarray,
    parents: np.ndarray,
    targets: np.ndarray,
    pins: Mapping[int, np.ndarray] | None = None,
    *,
    pin_axes: Mapping[int, tuple[int, ...]] | None = None,
    tolerance: float = TOLERANCE,
    max_iterations: int = MAX_ITERATIONS,
) -> tuple[np.ndarray, int]:
    """``(J, 3)`` positions nearest ``targets`` with the bone lengths of ``positions`` and
    the ``pins`` (joint → position; ``pin_axes``: joint → the axes held, default all three)
    held; returns them and the Newton iterations taken."""
    p0 = _finite(positions, "positions")
    goal = _finite(targets, "targets")
    parents = np.asarray(parents)
    n = len(p0)
    if goal.shape != p0.shape or p0.ndim != 2 or p0.shape[1] != 3 or parents.shape != (n,):
        raise AuthoringError(
            f"positions {p0.shape}, targets {goal.shape} and parents {parents.shape} "
            "must be (J, 3), (J, 3) and (J,)"
        )
    pins = {int(k): _finite(v, f"pin of joint {k}").reshape(3) for k, v in (pins or {}).items()}
    for joint in pins:
        if not 0 <= joint < n:
            raise AuthoringError(f"pinned joint {joint} is not one of the {n} joints")
    axes = {k: tuple((pin_axes or {}).get(k, (0, 1, 2))) for k in pins}
    bones, still = [], []  # (child, parent, length²) / (child, parent) of zero length
    for child in range(n):
        parent = int(parents[child])
        if parent < 0:
            continue
        length2 = float(np.sum((p0[child] - p0[parent]) ** 2))
        if length2 > 1e-18:
            bones.append((child, parent, length2))
        else:
            still.append((child, parent))
    lam = np.zeros(len(bones))
    p = goal.copy()
    for iteration in range(1, max_iterations + 1):
        kkt, rhs = _kkt(p, goal, bones, still, pins, axes, lam)
        solution = spsolve(kkt, rhs)
        if not np.isfinite(solution).all():
            raise AuthoringError("the IK's KKT system is singular (conflicting pins?)")
        step = solution[: 3 * n].reshape(n, 3)
        p = p + step
        lam = solution[3 * n : 3 * n + len(bones)]
        if _violation(p, bones, still, pins, axes) < tolerance and np.abs(step).max() < 1e-9:
            return p, iteration
    raise AuthoringError(
        f"the IK did not converge in {max_iterations} Newton iterations "
        f"(constraint violation {_violation(p, bones, still, pins, axes):.3g})"
    )


def _kkt(p, goal, bones, still, pins, axes, lam):
    """The Newton step's sparse KKT system ``[[H, Cᵀ], [C, 0]] [Δp; ν] = [−∇f; −c]``."""
    n = len(p)
    rows, cols, vals = [], [], []

    def add(r, c, v):
        rows.append(r)
        cols.append(c)
        vals.append(v)

    for k in range(3 * n):  # ∇²f = 2I
        add(k, k, 2.0)
    constraint = 3 * n
    residual = []
    for b, (i, j, length2) in enumerate(bones):
        d = p[i] - p[j]
        for r, sr in ((i, 1.0), (j, -1.0)):
            for c, sc in ((i, 1.0), (j, -1.0)):
                for a in range(3):  # λ_b (|p_i − p_j|² − d²)'s Hessian: 2λ_b [[I, −I], [−I, I]]
                    add(3 * r + a, 3 * c + a, 2.0 * lam[b] * sr * sc)
            for a in range(3):  # ∇g_b = ±2 (p_i − p_j)
                add(constraint + b, 3 * r + a, 2.0 * sr * d[a])
                add(3 * r + a, constraint + b, 2.0 * sr * d[a])
        residual.append(float(d @ d) - length2)
    constraint += len(bones)
    linear = [(i, j, (0, 1, 2)) for i, j in still] + [(k, None, axes[k]) for k in pins]
    for i, j, held in linear:  # p_i − p_j = 0, or p_k = c_k (on the axes held)
        for row, a in enumerate(held):
            add(constraint + row, 3 * i + a, 1.0)
            add(3 * i + a, constraint + row, 1.0)
            if j is not None:
                add(constraint + row, 3 * j + a, -1.0)
                add(3 * j + a, constraint + row, -1.0)
            residual.append(p[i, a] - (p[j, a] if j is not None else pins[i][a]))
        constraint += len(held)
    size = constraint
    kkt = csc_matrix(coo_matrix((vals, (rows, cols)), shape=(size, size)))
    rhs = np.concatenate([-2.0 * (p - goal).ravel(), -np.asarray(residual, dtype=np.float64)])
    return kkt, rhs


def _violation(p, bones, still, pins, axes) -> float:
    worst = 0.0
    for i, j, length2 in bones:
        worst = max(worst, abs(float(np.sum((p[i] - p[j]) ** 2)) - length2))
    for i, j in still:
        worst = max(worst, float(np.abs(p[i] - p[j]).max()))
    for k, c in pins.items():
        held = list(axes[k])
        worst = max(worst, float(np.abs(p[k, held] - c[held]).max()))
    return worst


def drag_targets(
    positions: np.ndarray, joint_names, drags: Mapping[str, np.ndarray], weights=None
) -> np.ndarray:
    """Targets ``p*``: each dragged joint moved by its drag, scaled by its painted weight
    (``weights``: joint name → 0…1, default 1; §5 "painting weights onto joints")."""
    names = list(joint_names)
    targets = _finite(positions, "positions").copy()
    for name, drag in drags.items():
        if name not in names:
            raise AuthoringError(f"the drag names joint {name!r}, which the skeleton does not have")
        weight = float((weights or {}).get(name, 1.0))
        targets[names.index(name)] += weight * _finite(drag, f"drag of {name}").reshape(3)
    return targets


# --- 2. minimal-rotation angles ----------------------------------------------------------------
def minimal_rotation_pose(
    local: np.ndarray, root_rotation: np.ndarray, skeleton: Skeleton, new_positions: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """New local rotations ``(J, 3, 3)`` and root rotation that put the skeleton's bones
    along ``new_positions`` (module docstring). ``local[0]`` is ignored: the root's world
    rotation is ``root_rotation``."""
    parents, offsets = skeleton.parents, skeleton.offsets
    n = len(parents)
    new = np.asarray(new_positions, dtype=np.float64)
    children = [
        [c for c in range(n) if parents[c] == j and np.linalg.norm(offsets[c]) > 0]
        for j in range(n)
    ]
    world = np.empty((n, 3, 3))
    out = np.asarray(local, dtype=np.float64).copy()
    for j in range(n):
        before = root_rotation if j == 0 else world[parents[j]] @ out[j]
        kids = children[j]
        if kids:
            old_dirs = np.array([before @ offsets[c] for c in kids])
            new_dirs = np.array([new[c] - new[j] for c in kids])
            before = _aligning(old_dirs, new_dirs) @ before
        world[j] = before
        if j > 0:
            out[j] = world[parents[j]].T @ world[j]
    return out, world[0]


def _aligning(old: np.ndarray, new: np.ndarray) -> np.ndarray:
    """The rotation taking the directions ``old`` onto ``new``: the minimal one for a single
    bone, the length-weighted best fit (Kabsch) for several."""
    if len(old) == 1:
        a = old[0] / np.linalg.norm(old[0])
        b = new[0] / np.linalg.norm(new[0])
        axis = np.cross(a, b)
        sin, cos = np.linalg.norm(axis), float(a @ b)
        if sin < 1e-12:
            if cos > 0:
                return np.eye(3)
            perpendicular = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
            return Rotation.from_rotvec(
                np.pi * perpendicular / np.linalg.norm(perpendicular)
            ).as_matrix()
        return Rotation.from_rotvec(axis / sin * np.arctan2(sin, cos)).as_matrix()
    u, _, vt = np.linalg.svd(new.T @ old)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def frame_pose(track: TargetTrack, skeleton: Skeleton, frame: int):
    """World positions ``(J, 3)``, local rotations ``(J, 3, 3)`` and the root's world
    rotation of one frame of a skeleton-mode track (the forward kinematics of
    :func:`rigmap.edits.skeleton_mode.skeleton_positions`)."""
    _check_frame(track, frame)
    k = len(skeleton.joint_names)
    vectors = track.values[frame, 5:].reshape(k, 3)
    local = Rotation.from_rotvec(vectors).as_matrix()
    root = track.root()
    world_r = np.empty((k, 3, 3))
    world_p = np.empty((k, 3))
    world_r[0] = turn_matrix(np.array([root.heading[frame]]))[0] @ local[0]
    world_p[0] = (root.x[frame], track.values[frame, 4], root.z[frame])
    for j in range(1, k):
        parent = skeleton.parents[j]
        world_r[j] = world_r[parent] @ local[j]
        world_p[j] = world_p[parent] + world_r[parent] @ skeleton.offsets[j]
    return world_p, local, world_r[0]


def pose_channels(
    track: TargetTrack, skeleton: Skeleton, frame: int, local, root_rotation, root_height: float
) -> np.ndarray:
    """The pose channels (root height, tilt, exp maps) of an edited frame, each rotation
    vector on the branch nearest the frame's own (so the edit's offset stays small)."""
    heading = track.root().heading[frame]
    tilt = turn_matrix(np.array([heading]))[0].T @ root_rotation
    rotations = np.concatenate([tilt[None], np.asarray(local)[1:]])
    vectors = Rotation.from_matrix(rotations).as_rotvec()
    old = track.values[frame, 5:].reshape(-1, 3)
    angle = np.linalg.norm(vectors, axis=1, keepdims=True)
    unit = np.divide(vectors, angle, out=np.zeros_like(vectors), where=angle > 1e-9)
    other = vectors - 2.0 * np.pi * unit
    closer = np.linalg.norm(other - old, axis=1) < np.linalg.norm(vectors - old, axis=1)
    vectors[closer] = other[closer]
    return np.concatenate([[root_height], vectors.ravel()])


# --- 3. edit signals -------------------------------------------------------------------------
def blend_weights(n_frames: int, frame: int, blend: int) -> np.ndarray:
    """1 at ``frame``, falling linearly to 0 ``blend + 1`` frames either side (§5)."""
    if blend < 0:
        raise AuthoringError(f"blend must be >= 0 frames, got {blend}")
    distance = np.abs(np.arange(n_frames) - frame)
    return np.clip(1.0 - distance / (blend + 1.0), 0.0, 1.0)


def offset_signal(n_frames: int, frame: int, delta: np.ndarray, blend: int) -> np.ndarray:
    """``d(t)`` ``(F, D)``: the key's difference ``delta`` at ``frame``, blended in and out."""
    return blend_weights(n_frames, frame, blend)[:, None] * np.asarray(delta, dtype=np.float64)


def timing_signal(n_frames: int, frame: int, shift: float, blend: int) -> np.ndarray:
    """``k(t)`` ``(F,)`` in frames: the pose of ``frame`` dragged by ``shift`` frames in time."""
    return blend_weights(n_frames, frame, blend) * float(shift)


def apply_pose_edit(
    track: TargetTrack,
    skeleton: Skeleton,
    frame: int,
    drags: Mapping[str, np.ndarray],
    blend: int,
    *,
    weights: Mapping[str, float] | None = None,
    pins: tuple[str, ...] = (),
) -> tuple[TargetTrack, np.ndarray]:
    """The track with one IK edit (drags in the track's length unit, world axes) keyed at
    ``frame`` and blended over ``blend`` frames; also returns the IK's joint positions."""
    _check_frame(track, frame)
    if track.channels != skeleton.channels():
        raise AuthoringError(f"{track.source}: its channels are not this skeleton's")
    names = list(skeleton.joint_names)
    for name in pins:
        if name not in names:
            raise AuthoringError(f"the pins name joint {name!r}, which the skeleton does not have")
    positions, local, root_rotation = frame_pose(track, skeleton, frame)
    targets = drag_targets(positions, names, drags, weights)
    pinned = {names.index(name): positions[names.index(name)] for name in pins}
    held = {k: (0, 1, 2) for k in pinned}
    if 0 not in pinned:  # the root stays where it stands on the ground (module docstring)
        pinned[0], held[0] = positions[0], (0, 2)
    solved, _ = bone_length_ik(positions, skeleton.parents, targets, pinned, pin_axes=held)
    new_local, new_root = minimal_rotation_pose(local, root_rotation, skeleton, solved)
    edited = pose_channels(track, skeleton, frame, new_local, new_root, solved[0, 1])
    delta = np.zeros(len(track.channels))
    delta[4:] = edited - track.values[frame, 4:]
    values = track.values + offset_signal(track.n_frames, frame, delta, blend)
    return track.with_values(values, source=f"{track.source} + IK edit at {frame}"), solved


def pin_feet(
    track: TargetTrack,
    skeleton: Skeleton,
    planted: np.ndarray,
    feet: tuple[str, ...],
    anchors: np.ndarray,
) -> TargetTrack:
    """§7.3's clean-up of an edited track: on every frame where foot ``k`` is ``planted``
    (``(F, K)`` booleans, the source's contacts), the IK pins that foot at ``anchors[f,
    k]`` (``(F, K, 3)``, the track's length unit: where the source planted it) with the
    rest of the body as near its pose as the bone lengths allow and the root's ground
    position held, then the minimal rotations give the frame's channels; an anchor the
    leg cannot reach raises :class:`AuthoringError`. Frames with no
    planted foot are left as they are (no blending: ours)."""
    names = list(skeleton.joint_names)
    missing = [f for f in feet if f not in names]
    if missing:
        raise AuthoringError(f"feet {missing} are not joints of the skeleton")
    planted = np.asarray(planted, dtype=bool)
    anchors = _finite(anchors, "anchors")
    if planted.shape != (track.n_frames, len(feet)) or anchors.shape != (*planted.shape, 3):
        raise AuthoringError(
            f"planted {planted.shape} and anchors {anchors.shape} must be "
            f"({track.n_frames}, {len(feet)}) and ({track.n_frames}, {len(feet)}, 3)"
        )
    columns = [names.index(f) for f in feet]
    values = track.values.copy()
    for frame in np.flatnonzero(planted.any(axis=1)):
        positions, local, root_rotation = frame_pose(track, skeleton, frame)
        pins, axes = {0: positions[0]}, {0: (0, 2)}
        for k in np.flatnonzero(planted[frame]):
            pins[columns[k]], axes[columns[k]] = anchors[frame, k], (0, 1, 2)
        solved, _ = bone_length_ik(positions, skeleton.parents, positions, pins, pin_axes=axes)
        new_local, new_root = minimal_rotation_pose(local, root_rotation, skeleton, solved)
        values[frame, 4:] = pose_channels(track, skeleton, frame, new_local, new_root, solved[0, 1])
    return track.with_values(values, source=f"{track.source} (feet pinned)")


def apply_timing_edit(track: TargetTrack, frame: int, shift: float, blend: int) -> TargetTrack:
    """``y(t) = x(t + k(t))``: every channel read at the shifted time (linear interpolation,
    clamped to the clip; ours), the root's per-frame step and turn included."""
    _check_frame(track, frame)
    k = timing_signal(track.n_frames, frame, shift, blend)
    when = np.clip(np.arange(track.n_frames) + k, 0, track.n_frames - 1)
    if np.any(np.diff(when) <= 0):
        raise AuthoringError(
            f"a shift of {shift} frames over a blend of {blend} folds time back on itself"
        )
    values = np.column_stack(
        [np.interp(when, np.arange(track.n_frames), column) for column in track.values.T]
    )
    return track.with_values(values, source=f"{track.source} + timing edit at {frame}")


def _check_frame(track: TargetTrack, frame: int) -> None:
    if not 0 <= frame < track.n_frames:
        raise AuthoringError(f"{track.source}: frame {frame} is outside 0..{track.n_frames - 1}")


def _finite(values, name: str) -> np.ndarray:
    values = np.asarray(values, dtype=np.float64)
    if not np.isfinite(values).all():
        raise AuthoringError(f"{name} has non-finite values")
    return values
