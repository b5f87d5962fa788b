"""The rig Jacobian's sparsity, and column colouring to difference many controls at once.

A control moves only the joints below its bone (a leg's IK target moves that
leg, a finger curl its finger), so a built-in rig's Jacobian is 12-13 % non-zero.
Two controls whose joint sets are disjoint can be perturbed in the same rig
evaluation: every row of the difference belongs to at most one of them, so
each control's column is read off its own rows. Grouping the columns so that
no two in a group share a row is a colouring of their intersection graph
(Curtis, Powell & Reid 1974, "On the estimation of sparse Jacobian
matrices"); a forward-difference Jacobian then costs ``1 + colours`` rig
evaluations per pose instead of ``1 + C`` and equals the dense one up to
rounding, since each row is computed from exactly the same perturbed control
values as when its control is perturbed alone.

The pattern is found once per rig, from central differences at the rig's
defaults and at ``PATTERN_PROBES`` poses drawn uniformly over the soft ranges
(ours), where every blend switch is partly on: an entry is structural when it
is non-zero at any of them. A rig whose rows depend on a control only inside
some region none of the probes visits (a hard threshold) would need more
probes; on the built-in rigs the coloured Jacobian equals the dense one to
1e-6 on the test clips' poses (tests/test_refine_sparsity.py). On the Blender
wolf (float32, central differences with a 1e-3 step) every non-zero probe entry
is kept: 24 % of the entries, 51 colours for 161 controls, the dense Jacobian
to 0.012 (float32 rounding over the step) at entries up to 172 on test poses;
a pattern thresholded like the built-in rigs' missed entries up to 0.74 and
raised the wolf's refined joint error from 0.24 to 0.35 cm².
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

#: random poses besides the defaults on which the pattern is probed (ours)
PATTERN_PROBES = 8
#: the probe's central-difference step in control units (ours; a float32 rig gets 1e-3)
PROBE_STEP = 1e-6


@dataclass(frozen=True)
class ColumnColouring:
    """A Jacobian's sparsity pattern ``(R, C_used)`` and a colouring of its columns.

    ``colours[c]`` is column ``c``'s group (``-1`` for a column that is zero
    everywhere: never differenced); no two columns of one group share a row.
    """

    pattern: np.ndarray  # (R, C_used) bool
    colours: np.ndarray  # (C_used,) int, -1 for a zero column

    @property
    def n_colours(self) -> int:
        return int(self.colours.max()) + 1 if self.colours.size and self.colours.max() >= 0 else 0

    @property
    def density(self) -> float:
        return float(self.pattern.mean())

    def groups(self) -> list[np.ndarray]:
        """Column positions of each colour, in colour order."""
        return [np.flatnonzero(self.colours == g) for g in range(self.n_colours)]

    def entries(self) -> tuple[np.ndarray, np.ndarray]:
        """``(rows, columns)`` of the pattern's non-zeros (row-major)."""
        return np.nonzero(self.pattern)

    @classmethod
    def of_pattern(cls, pattern: np.ndarray) -> ColumnColouring:
        """Greedy colouring, largest degree first (Welsh & Powell 1967)."""
        pattern = np.asarray(pattern, dtype=bool)
        if pattern.ndim != 2:
            raise ValueError(f"ColumnColouring: expected an (R, C) pattern, got {pattern.shape}")
        as_int = pattern.astype(np.int64)
        overlap = (as_int.T @ as_int) > 0  # columns sharing a row
        nonzero = np.flatnonzero(pattern.any(axis=0))
        degree = overlap[np.ix_(nonzero, nonzero)].sum(axis=1)
        order = nonzero[np.argsort(-degree, kind="stable")]
        colours = np.full(pattern.shape[1], -1, dtype=np.int64)
        for column in order:
            taken = set(colours[overlap[column] & (colours >= 0)].tolist())
            colour = 0
            while colour in taken:
                colour += 1
            colours[column] = colour
        return cls(pattern, colours)


def probe_pattern(rig, probes: int = PATTERN_PROBES, seed: int = 0) -> np.ndarray:
    """``(3J, C_used)`` bool: entries non-zero in a central-difference Jacobian at the rig's
    defaults or at ``probes`` random poses inside the soft ranges (ours: see the module)."""
    from rigmap.refine.jacobian import jacobian

    used = rig.controls.used_indices
    rng = np.random.default_rng(seed)
    Y = np.repeat(rig.controls.defaults[None], probes + 1, axis=0).astype(np.float64)
    step = 1e-3 if _coarse(rig) else PROBE_STEP
    Y[1:, used] = rng.uniform(
        rig.controls.lower[used], rig.controls.upper[used], (probes, len(used))
    )
    J = np.abs(jacobian(rig, Y, differences="central", chunk=None, step=step))
    # a row that does not depend on a control can still differ in its last bits (batched
    # torch arithmetic): 1e-8 on the quadruped against 1e-4 for the smallest real entry, so
    # entries below ten times the rounding of the positions over the step are dropped (ours).
    # A float32 rig keeps every non-zero: there that bound (0.2 on the wolf) is the size of
    # real entries, and an entry missed is a wrong Jacobian where a spurious one costs speed
    if _coarse(rig):
        return (J > 0).any(axis=0)
    X = np.abs(rig.evaluate(Y)).max()
    noise = 10 * np.finfo(np.float64).eps * X / step
    return (J > noise).any(axis=0)


def _coarse(rig) -> bool:
    return bool(getattr(rig, "computes_in_float32", False))


_COLOURINGS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def rig_colouring(rig) -> ColumnColouring:
    """The rig's column colouring, probed on the first call and kept while the rig lives.

    A ``CountingRig`` (``rigmap.evaluation``) is looked through to the rig it
    wraps, so every method evaluated on one rig shares it; the probe's own rig
    evaluations go through ``rig`` (counted where the caller counts, e.g. in a
    method's warm-up).
    """
    key = getattr(rig, "wrapped", rig)
    try:
        cached = _COLOURINGS.get(key)
    except TypeError:  # not weak-referenceable: probe every time
        return ColumnColouring.of_pattern(probe_pattern(rig))
    if cached is None:
        cached = ColumnColouring.of_pattern(probe_pattern(rig))
        _COLOURINGS[key] = cached
    return cached
