"""Rig Jacobians ``∂x/∂y`` with respect to the used controls (paper §4.3-4.4).

Finite differences treat the rig as a black box and work for any rig (one
batched ``evaluate`` call holds every perturbation); autodiff needs a
differentiable in-process rig and is exact.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from rigmap.rigs.base import Rig, RigInputError

JacobianMethod = Literal["finite_difference", "autodiff"]
JACOBIAN_METHODS = ("finite_difference", "autodiff")
DIFFERENCES = ("central", "forward")


def jacobian(
    rig: Rig,
    Y,
    method: JacobianMethod = "finite_difference",
    *,
    step: float | None = None,
    chunk: int | None = 64,
    differences: str = "central",
    columns=None,
    colouring=None,
    base=None,
) -> np.ndarray:
    """``(N, 3J, C_used)`` Jacobians of the COG-relative joint positions at ``Y``.

    ``Y`` holds full control vectors ``(N, C)`` (or one ``(C,)``). Finite
    differences are ``"central"`` or ``"forward"`` (one-sided: half the rig
    evaluations, an error of the order of the step) with ``step`` (default
    1e-6 in float64, 1e-3 in float32 or on a rig that computes in float32,
    ``rig.computes_in_float32``: Blender's), in the controls' own units. ``chunk``
    poses go to the rig per ``evaluate`` call (``None``: all in one call, what
    a worker pool wants). ``columns`` (positions among the used controls; finite
    differences only) differences those controls alone and leaves the other columns 0:
    for a caller that knows which controls can move its joints. ``colouring`` (a
    ``rigmap.refine.sparsity.ColumnColouring``) perturbs each colour's controls together —
    one rig evaluation (forward, or two central) per colour instead of per control — and
    reads each column off its own rows; entries outside the pattern are 0. With autodiff
    it sends one tangent per colour instead of one per control. ``base`` (forward
    differences only): the rig's COG-relative positions at ``Y`` (``(N, J, 3)`` or
    ``(N, 3J)``), already evaluated by the caller (refinement's residual), so the pose
    itself is not evaluated again: ``n`` rig evaluations per pose instead of ``n + 1``.
    """
    Y = np.asarray(Y)
    squeeze = Y.ndim == 1
    Y2 = Y[None] if squeeze else Y
    if Y2.ndim != 2 or Y2.shape[1] != rig.n_controls:
        raise RigInputError(
            f"jacobian of rig {rig.name!r}: expected controls of shape (N, {rig.n_controls}), "
            f"got {Y.shape}"
        )
    if step is not None and not (np.isfinite(step) and step > 0):
        raise RigInputError(f"jacobian step must be a finite number > 0, got {step!r}")
    if differences not in DIFFERENCES:
        raise ValueError(f"unknown differences {differences!r}; choose one of {DIFFERENCES}")
    chunk = len(Y2) if chunk is None else chunk
    n_used = len(rig.controls.used_indices)
    columns = np.arange(n_used) if columns is None else np.asarray(columns, dtype=np.int64)
    if columns.ndim != 1 or ((columns < 0) | (columns >= n_used)).any():
        raise RigInputError(
            f"jacobian of rig {rig.name!r}: columns must be positions among its {n_used} used "
            f"controls, got {columns!r}"
        )
    if method != "finite_difference" and len(columns) != n_used:
        raise ValueError("jacobian: columns are for finite differences only")
    if colouring is not None:
        if len(columns) != n_used:
            raise ValueError("jacobian: give columns or a colouring, not both")
        if colouring.pattern.shape != (3 * rig.n_joints, n_used):
            raise RigInputError(
                f"jacobian of rig {rig.name!r}: the colouring's pattern has shape "
                f"{colouring.pattern.shape}, expected ({3 * rig.n_joints}, {n_used})"
            )
    if base is not None:
        base = _checked_base(rig, base, len(Y2), method, differences)
    if method == "finite_difference":
        central = differences == "central"
        if colouring is not None:
            J = _coloured_difference(rig, Y2, step, max(chunk, 1), central, colouring, base)
        else:
            J = _finite_difference(rig, Y2, step, max(chunk, 1), central, columns, base)
    elif method == "autodiff":
        J = _autodiff(rig, Y2, chunk, colouring)
    else:
        raise ValueError(f"unknown Jacobian method {method!r}; choose one of {JACOBIAN_METHODS}")
    return J[0] if squeeze else J


def _checked_base(rig: Rig, base, n: int, method: str, differences: str) -> np.ndarray:
    """``base`` as ``(n, 3J)``, or a clear error when it cannot stand for the poses."""
    if method != "finite_difference" or differences != "forward":
        raise ValueError(
            "jacobian: base (the positions at Y) is for forward differences only, "
            f"got method={method!r}, differences={differences!r}"
        )
    base = np.asarray(base)
    if base.shape not in ((n, rig.n_joints, 3), (n, 3 * rig.n_joints)):
        raise RigInputError(
            f"jacobian of rig {rig.name!r}: base must be the positions at Y, shape "
            f"({n}, {rig.n_joints}, 3) or ({n}, {3 * rig.n_joints}), got {base.shape}"
        )
    return base.reshape(n, 3 * rig.n_joints)


def _finite_difference(
    rig: Rig,
    Y: np.ndarray,
    step: float | None,
    chunk: int,
    central: bool,
    columns: np.ndarray,
    base: np.ndarray | None = None,
) -> np.ndarray:
    dtype = np.float32 if Y.dtype == np.float32 else np.float64
    h = _step_of(rig, dtype, step)
    n_used = len(rig.controls.used_indices)
    moved = rig.controls.used_indices[columns]
    m = len(columns)
    k = np.arange(m)
    J = np.zeros((len(Y), 3 * rig.n_joints, n_used), dtype=dtype)
    for start in range(0, len(Y), chunk):
        Yc = Y[start : start + chunk].astype(dtype)
        n = len(Yc)
        # rows: for each pose, +h on each differenced control, then -h on each (central) or
        # the pose itself (forward, unless its positions are given)
        known = base is not None
        perturbed = np.repeat(Yc[:, None, :], 2 * m if central else m + (not known), axis=1)
        perturbed[:, k, moved] += h
        if central:
            perturbed[:, m + k, moved] -= h
        rows = perturbed.shape[1]
        X = rig.evaluate(perturbed.reshape(n * rows, -1)).reshape(n, rows, -1)
        behind = base[start : start + n, None, :] if known else X[:, m:]
        width = 2 * h if central else h
        J[start : start + n, :, columns] = ((X[:, :m] - behind) / width).transpose(0, 2, 1)
    return J


def _step_of(rig: Rig, dtype, step: float | None) -> float:
    # a float32 rig (Blender) loses a 1e-6 step in its rounding: on rigify_human the default
    # step's forward-difference Jacobian was 59 % off (median column 86 %), 1e-3's 0.15 %
    coarse = dtype == np.float32 or getattr(rig, "computes_in_float32", False)
    return step if step is not None else (1e-3 if coarse else 1e-6)


def _coloured_difference(
    rig: Rig,
    Y: np.ndarray,
    step: float | None,
    chunk: int,
    central: bool,
    colouring,
    base: np.ndarray | None = None,
) -> np.ndarray:
    """Finite differences with every colour's controls perturbed together (``sparsity``)."""
    dtype = np.float32 if Y.dtype == np.float32 else np.float64
    h = _step_of(rig, dtype, step)
    n_used = len(rig.controls.used_indices)
    g = colouring.n_colours
    # (g, C): +h on each control of a colour
    direction = np.zeros((g, rig.n_controls), dtype=dtype)
    coloured = np.flatnonzero(colouring.colours >= 0)
    direction[colouring.colours[coloured], rig.controls.used_indices[coloured]] = h
    rows, cols = colouring.entries()
    colour_of = colouring.colours[cols]
    J = np.zeros((len(Y), 3 * rig.n_joints, n_used), dtype=dtype)
    for start in range(0, len(Y), chunk):
        Yc = Y[start : start + chunk].astype(dtype)
        n = len(Yc)
        pose = Yc[:, None, :]
        if central:
            perturbed = np.concatenate([pose + direction, pose - direction], axis=1)  # (n, 2g, C)
        elif base is not None:  # the positions at the pose are given: (n, g, C), not copied
            perturbed = pose + direction
        else:  # the pose itself too: (n, g + 1, C)
            perturbed = np.concatenate([pose + direction, pose], axis=1)
        X = rig.evaluate(perturbed.reshape(n * perturbed.shape[1], -1)).reshape(n, -1, J.shape[1])
        ahead = X[:, :g]
        if central:
            behind = X[:, g:]
        else:
            behind = base[start : start + n, None, :] if base is not None else X[:, g : g + 1]
        width = 2 * h if central else h
        difference = (ahead - behind) / width  # (n, g, R)
        J[start : start + n, rows, cols] = difference[:, colour_of, rows]
    return J


# Autodiff batches every output (reverse) or input (forward) direction through the
# whole rig at once; these bounds keep that under ~1 GB on the built-in rigs.
AUTODIFF_POSES_PER_PASS = 8
AUTODIFF_DIRECTIONS_PER_PASS = 32


def _autodiff(rig: Rig, Y: np.ndarray, chunk: int, colouring=None) -> np.ndarray:
    if not rig.differentiable:
        raise ValueError(
            f"rig {rig.name!r} is not differentiable (it runs outside this process); "
            "use method='finite_difference'"
        )
    chunk = min(chunk, AUTODIFF_POSES_PER_PASS)
    # reverse mode costs one pass per output, forward mode one per input: pick the fewer
    n_used = len(rig.controls.used_indices)
    if colouring is not None:  # one tangent per colour, then each column off its own rows
        # as many dual rows per pass as dense forward mode's (ours: the memory bound)
        chunk = max(chunk, AUTODIFF_POSES_PER_PASS * n_used // max(colouring.n_colours, 1))
        rows, cols = colouring.entries()
        colour_of = colouring.colours[cols]
        J = np.zeros((len(Y), 3 * rig.n_joints, n_used), dtype=Y.dtype)
        for start in range(0, len(Y), chunk):
            compressed = _forward_dual(rig, Y[start : start + chunk], colouring.colours)
            J[start : start + chunk, rows, cols] = compressed[:, rows, colour_of]
        return J
    directional = _forward_dual if 3 * rig.n_joints > n_used else _reverse
    return np.concatenate(
        [directional(rig, Y[start : start + chunk]) for start in range(0, len(Y), chunk)]
    )


def _forward_dual(rig: Rig, Y: np.ndarray, colours: np.ndarray | None = None) -> np.ndarray:
    """Forward mode as one batched pass of dual numbers: pose n, direction m is row n·M + m.

    The directions are the used controls, or with ``colours`` (``(C_used,)``, -1 for
    none) the sum of each colour's controls: ``(N, 3J, colours)`` compressed columns.

    ``torch.func.jacfwd`` vmaps the same pass and ran 5-6x slower on the built-in
    rigs (quadruped 500 against 87 ms per pose, biped 300 against 60; equal to the
    last bit), so the directions go in as ordinary batch rows instead.
    """
    import torch
    import torch.autograd.forward_ad as forward_ad

    dtype = torch.float32 if Y.dtype == np.float32 else torch.float64
    used = torch.as_tensor(rig.controls.used_indices)
    direction = torch.arange(len(used))
    if colours is not None:
        keep = torch.as_tensor(colours >= 0)
        used, direction = used[keep], torch.as_tensor(colours)[keep]
    n, m = len(Y), int(direction.max()) + 1 if len(direction) else 0
    full = torch.as_tensor(Y, dtype=dtype)
    primal = full.repeat_interleave(m, dim=0)  # a copy: make_dual refuses stride-0 views
    tangent = torch.zeros(n, m, full.shape[1], dtype=dtype)
    tangent[:, direction, used] = 1.0
    with forward_ad.dual_level():
        x = rig.evaluate(forward_ad.make_dual(primal, tangent.reshape(n * m, -1)))
        dx = forward_ad.unpack_dual(x).tangent
    return dx.reshape(n, m, -1).permute(0, 2, 1).detach().numpy()


def _reverse(rig: Rig, Y: np.ndarray) -> np.ndarray:
    import torch

    dtype = torch.float32 if Y.dtype == np.float32 else torch.float64
    used = torch.as_tensor(rig.controls.used_indices)
    full = torch.as_tensor(Y, dtype=dtype)

    def positions_summed_over_batch(y_used):
        # poses are independent, so d(sum_n x_n)/d y_m = d x_m / d y_m
        x = rig.evaluate(full.index_copy(1, used, y_used))
        return x.reshape(x.shape[0], -1).sum(0)

    J = torch.func.jacrev(positions_summed_over_batch, chunk_size=AUTODIFF_DIRECTIONS_PER_PASS)(
        full[:, used]
    )  # (3J, n, C_used)
    return J.permute(1, 0, 2).detach().numpy()
