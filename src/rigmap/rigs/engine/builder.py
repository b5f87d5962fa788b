"""Building a torch rig: controls, control objects, joints and evaluation steps.

A character script creates control objects and feature units in dependency
order; each unit appends a *step* (a function of the evaluation context) that
reads control columns and writes world transforms.
:class:`~rigmap.rigs.engine.torch_rig.TorchRig` (``TorchRig(builder)``) runs the
result; the builder knows nothing of it, so the two modules import one way.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import torch

from rigmap.rigs.base import Control
from rigmap.rigs.engine.transforms import Transform, euler_matrix, rotation_product

TRANSLATE = ("tx", "ty", "tz")
ROTATE = ("rx", "ry", "rz")
SCALE = ("sx", "sy", "sz")
CHANNELS = TRANSLATE + ROTATE + SCALE

# Soft ranges an animator works in, per channel kind (cm, radians, factor).
DEFAULT_TRANSLATE_RANGE = 30.0
DEFAULT_ROTATE_RANGE = math.pi
DEFAULT_SCALE_RANGE = (0.25, 3.0)


class EvalContext:
    """State of one batched evaluation: control values and world transforms."""

    def __init__(self, Y: torch.Tensor):
        self.Y = Y
        self.n = Y.shape[0]
        self.dtype = Y.dtype
        self.xf: dict[str, Transform] = {}
        # local transforms of every control object, computed in one batched pass
        self.local: dict[str, Transform] = {}

    def value(self, column: int) -> torch.Tensor:
        return self.Y[:, column]

    def values(self, columns: list[int]) -> torch.Tensor:
        return self.Y[:, columns]

    def const(self, array) -> torch.Tensor:
        return torch.as_tensor(np.asarray(array, dtype=np.float64), dtype=self.dtype)


Step = Callable[[EvalContext], None]


@dataclass
class TransformControl:
    """A control object: nine transform channels, placed under a parent space.

    Its world transform is ``parent ∘ T(rest_offset + t) ∘ R(r, order) ∘ S(s)``.
    """

    name: str
    columns: dict[str, int]
    parent: str | None
    rest_offset: np.ndarray
    rotation_order: str = "xyz"

    def local(self, ctx: EvalContext) -> Transform:
        if self.name in ctx.local:
            return ctx.local[self.name]
        c = self.columns
        t = ctx.values([c["tx"], c["ty"], c["tz"]]) + ctx.const(self.rest_offset)
        R = euler_matrix(ctx.values([c["rx"], c["ry"], c["rz"]]), self.rotation_order)
        s = ctx.values([c["sx"], c["sy"], c["sz"]])
        return Transform(R * s[:, None, :], t)


#: the control objects' local transforms computed control by control (``(K, N, 3, 3)``), so
#: each one's ``R`` and ``t`` are contiguous: a batched 3 × 3 product with a strided slice of
#: the pose-major ``(N, K, 3, 3)`` array cost about 1.5x a contiguous one (ours, 1 024 poses).
#: The same values to the last bit; off: session 28's pose-major layout (for
#: ``benchmarks/refine.py``'s same-run comparison)
CONTROL_MAJOR_LOCALS = True


def batched_locals(controls: list[TransformControl]):
    """Precompute every control's local transform with one Euler pass per rotation order.

    Rigs have ~80 control objects; evaluating them one by one costs ~30 small
    torch ops each, which dominates small batches (refinement evaluates one
    frame at a time).
    """
    by_order: dict[str, list[TransformControl]] = {}
    for ctrl in controls:
        by_order.setdefault(ctrl.rotation_order, []).append(ctrl)
    plans = []
    for order, group in by_order.items():
        cols = np.array([[c.columns[ch] for ch in CHANNELS] for c in group])  # (K, 9)
        offsets = np.stack([c.rest_offset for c in group])
        plans.append((order, [c.name for c in group], cols, offsets))

    def blocks(ctx: EvalContext) -> list[tuple[list[str], torch.Tensor, torch.Tensor]]:
        """Per rotation order: the controls' names, ``R`` ``(K, N, 3, 3)``, ``t`` ``(K, N, 3)``."""
        out = []
        for order, names, cols, offsets in plans:
            # channel by channel, (9, K, N): each control's R and t come out contiguous
            index = torch.as_tensor(cols.T.reshape(-1))
            values = ctx.Y.t().index_select(0, index).reshape(9, len(names), ctx.n)
            t = torch.stack([values[0], values[1], values[2]], dim=-1) + ctx.const(offsets)[:, None]
            angles = [(values[3 + "xyz".index(axis)], axis) for axis in order]
            scale = torch.stack([values[6], values[7], values[8]], dim=-1)[..., None, :]
            out.append((names, rotation_product(angles) * scale, t))
        return out

    def fill(ctx: EvalContext) -> None:
        if not CONTROL_MAJOR_LOCALS:
            return _fill_pose_major(ctx)
        for names, R, t in blocks(ctx):
            for k, name in enumerate(names):
                ctx.local[name] = Transform(R[k], t[k])

    def _fill_pose_major(ctx: EvalContext) -> None:  # session 28's layout, (N, K, ...)
        for order, names, cols, offsets in plans:
            values = ctx.Y[:, torch.as_tensor(cols.reshape(-1))].reshape(ctx.n, len(names), 9)
            t = values[..., 0:3] + ctx.const(offsets)
            R = euler_matrix(values[..., 3:6], order) * values[..., None, 6:9]
            for k, name in enumerate(names):
                ctx.local[name] = Transform(R[:, k], t[:, k])

    fill.blocks = blocks  # the structured pass keeps the blocks (rigmap.rigs.engine.structured)
    return fill


@dataclass
class Attribute:
    """A custom scalar channel (IK/FK blend, foot roll, curl …)."""

    name: str
    column: int

    def __call__(self, ctx: EvalContext) -> torch.Tensor:
        return ctx.value(self.column)


@dataclass
class JointSpec:
    name: str
    parent: str | None


@dataclass
class RigBuilder:
    """Accumulates controls, joints and steps; ``TorchRig(builder)`` makes the rig."""

    name: str
    controls: list[Control] = field(default_factory=list)
    joints: list[JointSpec] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    cog: str = "cog"
    # rest world position of every named transform (rest orientations are world-aligned)
    rest: dict[str, np.ndarray] = field(default_factory=dict)
    transform_controls: list[TransformControl] = field(default_factory=list)

    def offset_to(self, parent: str | None, world_position) -> np.ndarray:
        """Rest offset that puts a child of ``parent`` at ``world_position`` (cm)."""
        target = np.asarray(world_position, dtype=np.float64)
        return target if parent is None else target - self.rest[parent]

    def set_rest(self, name: str, world_position) -> None:
        self.rest[name] = np.asarray(world_position, dtype=np.float64)

    # --- controls -------------------------------------------------------
    def _add(self, control: Control) -> int:
        self.controls.append(control)
        return len(self.controls) - 1

    def attribute(
        self,
        name: str,
        *,
        default: float = 0.0,
        lower: float = 0.0,
        upper: float = 1.0,
        used: bool = True,
        group: str,
    ) -> Attribute:
        return Attribute(
            name, self._add(Control(name, "scalar", default, lower, upper, used, group))
        )

    def transform_control(
        self,
        name: str,
        *,
        parent: str | None,
        offset: Iterable[float] = (0.0, 0.0, 0.0),
        group: str,
        used: Iterable[str] | str = (),
        rotation_order: str = "xyz",
        translate_range: float = DEFAULT_TRANSLATE_RANGE,
        rotate_range: float | dict[str, tuple[float, float]] = DEFAULT_ROTATE_RANGE,
        scale_range: tuple[float, float] = DEFAULT_SCALE_RANGE,
        add_step: bool = True,
    ) -> TransformControl:
        """Nine channels ``name.tx … name.sz``; ``used`` names the keyed ones.

        With ``add_step`` its world transform is computed (into ``ctx.xf[name]``)
        at this point of the evaluation order.
        """
        used_set = set(used.split() if isinstance(used, str) else used)
        unknown = used_set - set(CHANNELS)
        if unknown:
            raise ValueError(f"control {name!r}: unknown channels {sorted(unknown)}")
        columns: dict[str, int] = {}
        for ch in CHANNELS:
            if ch in TRANSLATE:
                kind, default, lo, hi = "translate", 0.0, -translate_range, translate_range
            elif ch in ROTATE:
                kind, default = "rotate", 0.0
                if isinstance(rotate_range, dict):
                    lo, hi = rotate_range.get(ch, (-DEFAULT_ROTATE_RANGE, DEFAULT_ROTATE_RANGE))
                else:
                    lo, hi = -rotate_range, rotate_range
            else:
                kind, default, (lo, hi) = "scale", 1.0, scale_range
            columns[ch] = self._add(
                Control(f"{name}.{ch}", kind, default, lo, hi, ch in used_set, group)
            )
        ctrl = TransformControl(
            name, columns, parent, np.asarray(offset, dtype=np.float64), rotation_order
        )
        if parent is not None and parent not in self.rest:
            raise ValueError(f"control {name!r}: parent {parent!r} has no rest position yet")
        self.rest[name] = ctrl.rest_offset + (self.rest[parent] if parent is not None else 0.0)
        self.transform_controls.append(ctrl)
        if add_step:
            self.step(_world_of(ctrl))
        return ctrl

    # --- joints and steps ---------------------------------------------------
    def joint(self, name: str, parent: str | None) -> str:
        if any(j.name == name for j in self.joints):
            raise ValueError(f"joint {name!r} declared twice")
        if parent is not None and not any(j.name == parent for j in self.joints):
            raise ValueError(f"joint {name!r}: parent {parent!r} not declared yet")
        self.joints.append(JointSpec(name, parent))
        return name

    def step(self, fn: Step) -> Step:
        self.steps.append(fn)
        return fn


def _world_of(ctrl: TransformControl) -> Step:
    def step(ctx: EvalContext) -> None:
        local = ctrl.local(ctx)
        ctx.xf[ctrl.name] = local if ctrl.parent is None else ctx.xf[ctrl.parent].compose(local)

    return step
