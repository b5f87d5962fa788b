"""Planted feet held exactly: a last IK pass on the rig's foot controls at the contacts.

Refinement weighs planted feet more (``MapSettings.foot_weight``) but cannot hold them
where the rig does not reach every target: the mapped biped's feet slid more than the
source's. This pass makes the contacts hard constraints. It moves only the *foot
controls*: the used, unheld controls that move a contact joint but neither the mapping's
origin (the hips) nor the root of the contact joint's leg (the thigh), found by probing
the rig (on the biped: the leg IK controls and the foot roll; never the root, the COG or
the spine), so root motion, scale and the body stay as mapped. On every planted frame,
Gauss-Newton steps of least change (in training stds) put each planted joint's
horizontal position (x, z) on its pin; its height is left to the mapping. The change is
faded in and out over :data:`BLEND_S` around each plant, so no control jumps when a foot
lands or lifts. All values here are ours.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt

from rigmap.map.contacts import Contacts
from rigmap.map.world_subset_rig import WorldSubsetRig

ITERATIONS = 20  # Gauss-Newton steps at most (ours)
TOLERANCE_CM = 1e-3  # a planted joint this close to its pin is held (ours)
BLEND_S = 0.1  # the hold's change fades over this long before and after a plant (ours)
PROBE_STD = 1e-3  # finite-difference step, training stds (ours)
MOVES_CM = 1e-6  # a probe moving a joint less than this (per probe) does not move it
# a rig computing in float32 (Blender's) rounds positions to ~1e-5 of their size: a larger
# step and threshold keep its rounding out of the Jacobian and the foot controls (ours)
FLOAT32_PROBE_STD, FLOAT32_MOVES_CM = 0.05, 1e-2


def _probe(rig) -> tuple[float, float]:
    """The finite-difference step (std) and the "does not move" threshold (cm) for ``rig``."""
    if getattr(rig, "computes_in_float32", False):
        return FLOAT32_PROBE_STD, FLOAT32_MOVES_CM
    return PROBE_STD, MOVES_CM


RIDGE = 0.01  # cm² per std²: damping where the leg is straight and the foot cannot reach
MAX_STEP_STD = 1.0  # largest change of a foot control in one step, training stds (ours)
GROUND = [0, 2]  # rig axes: X and Z span the ground


@dataclass(frozen=True)
class HeldContacts:
    """Used controls ``(F, U)`` with the contacts held, and what the hold did."""

    controls: np.ndarray
    foot_controls: tuple[str, ...]
    residual_cm: float  # the largest horizontal distance of a planted joint from its pin
    rig_evaluations: int


def foot_controls(rig, row: np.ndarray, contacts: Contacts, origin: str, scale):
    """Which used controls (scale > 0) move a contact joint horizontally but neither
    ``origin`` nor the root of a contact joint's leg, probed at the full control ``row``:
    ``(U,)`` flags, and ``(U, P)`` flags of the contact joints each one moves."""
    used = rig.controls.used_indices
    step, still = _probe(rig)
    scale = np.asarray(scale, dtype=np.float64)
    fixed = sorted({origin, *(_leg_root(rig, f, origin) for f in contacts.feet)})
    view = WorldSubsetRig(rig, [*contacts.feet, *fixed])
    probes = np.repeat(np.asarray(row, dtype=np.float64)[None], len(used) + 1, axis=0)
    for k, c in enumerate(used):
        probes[k + 1, c] += step * max(scale[k], 0.0)
    world = np.asarray(view.evaluate(probes), dtype=np.float64)
    shift = world[1:] - world[0]
    feet = len(contacts.feet)
    moves = np.linalg.norm(shift[:, :feet][:, :, GROUND], axis=2) > still  # (U, P)
    body = (np.linalg.norm(shift[:, feet:], axis=2) > still).any(axis=1)
    flags = moves.any(axis=1) & ~body & (scale > 0)
    return flags, moves & flags[:, None]


def _chain(rig, joint: str) -> list[str]:
    """``joint`` and its ancestors up to the root; ``[joint]`` for a rig without hierarchy."""
    parents = getattr(rig, "parents", None)
    if parents is None:
        return [joint]
    names = list(rig.joint_names)
    j = names.index(joint)
    chain = [names[j]]
    while parents[j] >= 0:
        j = int(parents[j])
        chain.append(names[j])
    return chain


def _leg_root(rig, foot: str, origin: str) -> str:
    """The ancestor of ``foot`` whose parent is ``origin`` (the thigh); ``origin`` when the
    rig has no hierarchy or ``origin`` is not an ancestor of ``foot``."""
    chain = _chain(rig, foot)
    return next((c for c, p in itertools.pairwise(chain) if p == origin), origin)


def hold_contacts(
    rig, Y_used, pinned, contacts: Contacts, joints, origin: str, scale, fps: float
) -> HeldContacts:
    """``Y_used`` ``(F, U)`` with every planted joint of ``contacts`` on its pin: the
    horizontal position of ``pinned`` ``(F, K, 3)`` (world cm, ``joints`` order; see
    :func:`reachable_pins`).
    ``scale`` is per used control (training std; 0 for held controls, which stay)."""
    Y = np.asarray(Y_used, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    frames = np.flatnonzero(contacts.planted.any(axis=1))
    if frames.size == 0:
        return HeldContacts(Y.copy(), (), 0.0, 0)
    flags, moves = foot_controls(rig, rig.expand_used(Y[frames[:1]])[0], contacts, origin, scale)
    columns = np.flatnonzero(flags)
    if columns.size == 0:
        return HeldContacts(Y.copy(), (), float("nan"), len(scale) + 1)
    pins = np.asarray(pinned)[frames][:, [list(joints).index(f) for f in contacts.feet]]
    solve = _Solve(
        rig,
        Y[frames],
        columns,
        scale[columns],
        contacts.planted[frames],
        pins[:, :, GROUND],
        WorldSubsetRig(rig, list(contacts.feet)),
    )
    change, residual = solve.run()
    full = np.zeros((len(Y), len(columns)))
    full[frames] = change
    plants = contacts.planted.astype(np.float64) @ moves[columns].T.astype(np.float64) > 0
    held = Y.copy()
    held[:, columns] += _faded(full, plants, round(BLEND_S * fps)) * scale[columns]
    return HeldContacts(
        held,
        tuple(rig.used_controls[c] for c in columns),
        residual,
        solve.evaluations + len(scale) + 1,
    )


def reachable_pins(rig, pinned, source, contacts: Contacts, joints) -> np.ndarray:
    """``pinned`` with each toe pin (a contact joint below another, its heel, in the rig's
    hierarchy) moved toward its heel's pin where, on frames both are planted, the pins are
    farther apart than the source's heel and toe (the planted intervals' means differ
    where the source slides; the foot could not reach both pins)."""
    pins = np.array(pinned, dtype=np.float64, copy=True)
    source = np.asarray(source, dtype=np.float64)
    column = {f: list(joints).index(f) for f in contacts.feet}
    for kb, toe in enumerate(contacts.feet):
        for ka, heel in enumerate(contacts.feet):
            if ka == kb or not _is_ancestor(rig, heel, toe):
                continue
            for first, last in contacts.intervals(kb):
                both = np.flatnonzero(contacts.planted[first : last + 1, ka]) + first
                if both.size == 0:
                    continue
                a, b = column[heel], column[toe]
                gap = pins[both, b][:, GROUND] - pins[both, a][:, GROUND]
                reach = np.linalg.norm(
                    source[both, b][:, GROUND] - source[both, a][:, GROUND], axis=1
                )
                excess = np.linalg.norm(gap, axis=1) - reach
                worst = int(np.argmax(excess))
                if excess[worst] > 0:
                    shift = -gap[worst] / np.linalg.norm(gap[worst]) * excess[worst]
                    pins[first : last + 1, b, 0] += shift[0]
                    pins[first : last + 1, b, 2] += shift[1]
    return pins


def _is_ancestor(rig, joint: str, of: str) -> bool:
    return joint in _chain(rig, of)[1:]


class _Solve:
    """Damped Gauss-Newton of least change (training stds) on the planted frames' pins; a
    frame whose step made it worse goes back half that step (backtracking)."""

    def __init__(self, rig, Y, columns, scale, planted, pins, view):
        self.rig, self.Y, self.columns, self.scale = rig, Y, columns, scale
        self.mask = np.repeat(planted, 2, axis=1).astype(np.float64)  # (N, 2P) rows x, z
        self.pins, self.view, self.evaluations = pins.reshape(len(Y), -1), view, 0
        self.step = _probe(rig)[0]

    def ground(self, change: np.ndarray, frames: np.ndarray, probes: bool = True) -> np.ndarray:
        """``(n, 1 + m, 2P)`` joints' x, z of ``frames`` at ``change`` (and each probe)."""
        m = len(self.columns) if probes else 0
        rows = np.repeat(self.Y[frames, None], 1 + m, axis=1)
        rows[:, :, self.columns] += (change[frames] * self.scale)[:, None]
        for k in range(m):
            rows[:, k + 1, self.columns[k]] += self.step * self.scale[k]
        flat = self.rig.expand_used(rows.reshape(-1, rows.shape[2]))
        world = np.asarray(self.view.evaluate(flat))
        self.evaluations += len(world)
        return world[:, :, GROUND].reshape(len(frames), 1 + m, -1)

    def distance(self, ground: np.ndarray, frames) -> tuple[np.ndarray, np.ndarray]:
        """The masked residual ``(n, 2P)`` and each frame's largest joint distance (cm)."""
        error = (self.pins[frames] - ground) * self.mask[frames]
        return error, np.linalg.norm(error.reshape(len(error), -1, 2), axis=2).max(axis=1)

    def run(self) -> tuple[np.ndarray, float]:
        n = len(self.Y)
        change, step = np.zeros((n, len(self.columns))), np.zeros((n, len(self.columns)))
        best, active = np.full(n, np.inf), np.arange(n)
        for _ in range(ITERATIONS):
            ground = self.ground(change, active)
            error, size = self.distance(ground[:, 0], active)
            worse = size > best[active]
            back = active[worse]
            change[back] -= step[back] / 2
            step[back] /= 2
            best[active[~worse]] = size[~worse]
            go = ~worse & (size > TOLERANCE_CM)
            J = (ground[go, 1:] - ground[go, :1]) / self.step * self.mask[active[go], None]
            new = _least_change(J, error[go])
            new /= np.maximum(1.0, np.abs(new).max(axis=1, keepdims=True) / MAX_STEP_STD)
            step[active[go]] = new
            change[active[go]] += new
            active = np.sort(np.concatenate([back, active[go]]))
            if active.size == 0:
                break
        everything = np.arange(n)
        _, size = self.distance(self.ground(change, everything, probes=False)[:, 0], everything)
        return change, float(size.max())


def _least_change(J: np.ndarray, error: np.ndarray) -> np.ndarray:
    """Per frame the smallest step ``dz`` with ``Jᵀ dz = error`` (``J`` ``(N, m, R)``):
    ``dz = J (JᵀJ + λI)⁻¹ error`` (Levenberg's damping :data:`RIDGE`); rows of unplanted
    joints are zero and stay so."""
    gram = np.einsum("nmr,nms->nrs", J, J) + RIDGE * np.eye(J.shape[2])
    return np.einsum("nmr,nr->nm", J, np.linalg.solve(gram, error[:, :, None])[:, :, 0])


def _faded(change: np.ndarray, plants: np.ndarray, width: int) -> np.ndarray:
    """``change`` ``(F, m)`` kept on each control's planted frames (``plants`` ``(F, m)``),
    zero from ``width + 1`` frames away from them, linear in between (a gap too short to
    fade out goes straight from one plant's change to the next)."""
    out = np.zeros_like(change)
    frames = np.arange(len(change))
    for k in range(change.shape[1]):
        if not plants[:, k].any():
            continue
        far = distance_transform_edt(~plants[:, k]) > width
        anchors = np.flatnonzero(plants[:, k] | far)
        values = np.where(plants[anchors, k], change[anchors, k], 0.0)
        out[:, k] = np.interp(frames, anchors, values)
    return out
