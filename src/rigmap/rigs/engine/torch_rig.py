"""A rig evaluated in-process by torch: batched, differentiable, fast."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch

from rigmap.rigs.base import ControlTable, Pose, Rig, _is_torch
from rigmap.rigs.engine.builder import EvalContext, RigBuilder, batched_locals

# Large batches are evaluated in chunks so memory stays bounded (~100 MB a chunk).
DEFAULT_CHUNK = 16_384
#: batch sizes traced for :meth:`TorchRig.replaying_traces` (ours): a batch is padded to the
#: next one, so at most about half a batch is wasted, and a few traces (0.5-0.7 s each to
#: build) serve every batch; a larger batch is split at the largest, which is also the size
#: with the highest pose rate (quadruped, one thread, 3 440 poses in chunks, 4 alternating
#: repeats at a load of 1-2: 14 100 poses/s at 1 024, 13 300 at 512, 11 800 at 1 720 padded
#: to a 1 760 trace — the larger traces fall out of the cache, so 1 760 and 2 048 went)
TRACE_SIZES = (16, 32, 64, 128, 256, 512, 1024)
#: what a caller that chunks its poses should send while traces replay (the largest size)
TRACED_POSES_PER_CALL = TRACE_SIZES[-1]


class TorchRig(Rig):
    """Runs a :class:`RigBuilder`'s steps on a batch of control vectors."""

    differentiable = True

    def __init__(self, builder: RigBuilder, *, description: str = "", chunk: int = DEFAULT_CHUNK):
        self.name = builder.name
        self.description = description
        self.controls = ControlTable(builder.controls)
        self.joint_names = [j.name for j in builder.joints]
        index = {name: i for i, name in enumerate(self.joint_names)}
        self.parents = np.array(
            [-1 if j.parent is None else index[j.parent] for j in builder.joints], dtype=np.int64
        )
        # rest (default-control) world positions, for checks and drawing
        self.rest_positions = np.stack([builder.rest[j] for j in self.joint_names])
        # Euler order of every control object (name -> "xyz" …), for scripts that set rotations
        self.rotation_orders = {c.name: c.rotation_order for c in builder.transform_controls}
        self._steps = [batched_locals(builder.transform_controls), *builder.steps]
        self._cog = builder.cog
        self._chunk = chunk
        self._replay = 0  # > 0 while numpy batches go through TorchScript traces

    @contextmanager
    def replaying_traces(self) -> Iterator[None]:
        """Numpy batches evaluated by this rig's TorchScript traces while the block runs.

        Each batch is padded with default poses to the next of ``TRACE_SIZES`` (split
        at the largest) and replayed by :meth:`traced_pose`, about twice as fast as the
        eager pass (quadruped, one thread: 75 poses 34 against 77 ms, 1 752 poses 200
        against 460; equal to the last bit). A trace is built once per size and dtype
        (about 1 s). Torch inputs (autodiff) still run eagerly. The first use builds the
        float64 traces of every size at once, so the one-off cost falls where the caller
        enters the block first (an evaluation's untimed warm-up) and not inside later timing.
        """
        for size in TRACE_SIZES:
            self.traced_pose(size, torch.float64)
        self._replay += 1
        try:
            yield
        finally:
            self._replay -= 1

    @property
    def poses_per_call(self) -> int | None:
        """The batch size a caller that chunks its poses should send (None: its own choice).

        While traces replay, ``TRACED_POSES_PER_CALL`` (a trace size, so nothing is padded
        beyond it); eager evaluation has no preferred size.
        """
        return TRACED_POSES_PER_CALL if self._replay else None

    def _pose(self, Y) -> Pose:
        if _is_torch(Y):
            return self._pose_torch(Y)
        dtype = torch.float32 if Y.dtype == np.float32 else torch.float64
        if self._replay:
            return self._pose_replayed(Y, dtype)
        with torch.no_grad():
            parts = [
                self._pose_torch(
                    torch.from_numpy(np.ascontiguousarray(Y[i : i + self._chunk])).to(dtype)
                )
                for i in range(0, max(len(Y), 1), self._chunk)
            ]
        return Pose(*(np.concatenate([p[k].numpy() for p in parts]) for k in range(3)))

    def _pose_replayed(self, Y: np.ndarray, dtype: torch.dtype) -> Pose:
        parts = []
        largest = TRACE_SIZES[-1]
        with torch.no_grad():
            for start in range(0, max(len(Y), 1), largest):
                chunk = Y[start : start + largest]
                n = len(chunk)
                size = next(s for s in TRACE_SIZES if s >= n)
                padded = np.empty((size, Y.shape[1]), dtype=np.float64)
                padded[:n] = chunk
                padded[n:] = self.controls.defaults
                out = self.traced_pose(size, dtype)(torch.from_numpy(padded).to(dtype))
                parts.append([o[:n].numpy() for o in out])
        return Pose(*(np.concatenate([p[k] for p in parts]) for k in range(3)))

    def _pose_torch(self, Y: torch.Tensor) -> Pose:
        ctx = EvalContext(Y)
        for step in self._steps:
            step(ctx)
        missing = [j for j in self.joint_names if j not in ctx.xf]
        if missing:
            raise RuntimeError(f"rig {self.name!r}: no step wrote joints {missing[:5]}")
        world = torch.stack([ctx.xf[j].t for j in self.joint_names], dim=1)
        cog = ctx.xf[self._cog]
        return Pose(world - cog.t[:, None, :], cog.t, cog.R)

    def traced_pose(self, n: int, dtype: torch.dtype = torch.float64):
        """``Y (n, C) tensor -> (positions, cog, cog_rotation)`` as a TorchScript trace of this
        rig for batches of exactly ``n`` poses, cached per ``(n, dtype)``.

        Evaluating a handful of poses is dominated by the ~2 000 small torch operations of
        one pass (about 8 ms on the biped); a trace replays them without Python and runs
        about twice as fast. It is valid because no rig step branches on control values
        (tested against :meth:`pose` on random controls). For interactive work on small
        fixed batches (:mod:`rigmap.map.interactive_pose`); it carries no gradient.
        """
        key = (int(n), dtype)
        cache = self.__dict__.setdefault("_traces", {})
        if key not in cache:
            example = torch.as_tensor(self.controls.defaults, dtype=dtype).expand(n, -1).clone()

            def pose_tuple(Y):
                pose = self._pose_torch(Y)
                return pose.positions, pose.cog, pose.cog_rotation

            with torch.no_grad(), warnings.catch_warnings():
                warnings.simplefilter("ignore", torch.jit.TracerWarning)  # constants, as meant
                # torch 2.13 marks jit.trace deprecated; torch.compile would need a C++
                # toolchain and seconds of start-up per batch size (the traced-pose test
                # guards the day trace stops matching the eager rig)
                warnings.simplefilter("ignore", DeprecationWarning)
                cache[key] = torch.jit.trace(pose_tuple, (example,), check_trace=False)
        return cache[key]

    def world_transforms(self, Y) -> dict:
        """Every named world transform of one evaluation (controls, joints); for tests."""
        Y, _ = self._check_controls(Y)
        Yt = Y if _is_torch(Y) else torch.as_tensor(Y)
        ctx = EvalContext(Yt)
        for step in self._steps:
            step(ctx)
        return ctx.xf
