"""A rig evaluated in-process by torch: batched, differentiable, fast."""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import torch

from rigmap.rigs.base import ControlTable, Pose, Rig, _is_torch
from rigmap.rigs.engine.builder import EvalContext, RigBuilder, batched_locals
from rigmap.rigs.engine.compiled import CompiledPass
from rigmap.rigs.engine.structured import StructuredPass

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
#: one trace replays batches of every size (ours): recorded on ``GENERIC_TRACE_SIZE`` poses, it
#: gives the eager positions at other sizes on the built-in rigs (no step bakes the batch size
#: in; checked per rig and dtype when it is built, else the padded ``TRACE_SIZES`` serve). One
#: trace instead of 7 cuts the one-off cost about 7x, and nothing is padded (quadruped, one
#: thread, the same run: 75 poses 74 ms against 92 padded to 128, 300 poses 145 against 232)
GENERIC_TRACE = True
GENERIC_TRACE_SIZE = 16
#: calls a new trace gets at build time: TorchScript's profiling executor records the first
#: and optimises on the second, each about as slow as the trace itself (quadruped, one
#: thread: 0.22-0.31 s each, then 6 ms for 16 poses), so they are paid where the trace is
#: built, not in a timed pass (ours: it is what torch's executor needs)
JIT_WARMUP_CALLS = 2
#: batches of up to ``STRUCTURED_MAX_POSES`` poses run the steps by structure
#: (:class:`~rigmap.rigs.engine.structured.StructuredPass`, equal to the step-by-step
#: reference to 1e-10 in float64, float32 positions to the bit); off: the reference
#: (:meth:`TorchRig.reference_pose`) everywhere
STRUCTURED = True
#: the largest batch the structured pass runs (ours, ``benchmarks/rig_pass.py``, one thread):
#: it saves torch's per-operation overhead, which dominates small batches (quadruped forward
#: and backward: 100 poses 1.6x, 256 1.3x, 512 1.1x faster), but its folded instances turn
#: products with a shared constant into batched ones, so larger batches ran slower (1 024
#: poses 0.79x, 4 096 0.86x) and keep the reference; so do TorchScript traces, which have
#: no Python overhead to save (1 024 poses replayed 0.93x)
STRUCTURED_MAX_POSES = 512
#: torch batches the structured pass would run go through its inductor-compiled graphs
#: (:mod:`rigmap.rigs.engine.compiled`) instead, padded to ``COMPILED_POSES`` rows. Off by
#: default (ours): 2.7x faster forward and backward at 128 float32 quadruped rows (27 ->
#: 10 ms, one thread) but 107 s to compile per rig and dtype on a cold cache, which only a
#: long loop (the joint-space fit's 3 400 steps) repays
COMPILED = False
#: the compiled graphs' batch size (ours: the joint-space fit's minibatch)
COMPILED_POSES = 128


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

        Each batch (split at ``TRACED_POSES_PER_CALL``) is replayed by :meth:`generic_trace`,
        one trace for every batch size; where that is off or does not reproduce this rig,
        it is padded with default poses to the next of ``TRACE_SIZES`` and replayed by
        :meth:`traced_pose`. Either is about twice as fast as the eager pass (quadruped,
        one thread: 75 poses 34 against 77 ms, 1 752 poses 200 against 460; equal to the
        last bit). A trace is built once per size and dtype and run ``JIT_WARMUP_CALLS``
        times at once (0.7-0.9 s in all per trace at a load of 1-2). Torch inputs
        (autodiff) still run eagerly. The first use builds the float64 trace(s) at once,
        so the one-off cost falls where the caller enters the block first (an
        evaluation's untimed warm-up) and not inside later timing.
        """
        if self.generic_trace(torch.float64) is None:
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
        generic = self.generic_trace(dtype)
        with torch.no_grad():
            for start in range(0, max(len(Y), 1), largest):
                chunk = Y[start : start + largest]
                n = len(chunk)
                if generic is not None and n > 0:
                    out = generic(torch.from_numpy(np.ascontiguousarray(chunk)).to(dtype))
                    parts.append([o.numpy() for o in out])
                    continue
                size = next(s for s in TRACE_SIZES if s >= n)
                padded = np.empty((size, Y.shape[1]), dtype=np.float64)
                padded[:n] = chunk
                padded[n:] = self.controls.defaults
                out = self.traced_pose(size, dtype)(torch.from_numpy(padded).to(dtype))
                parts.append([o[:n].numpy() for o in out])
        return Pose(*(np.concatenate([p[k] for p in parts]) for k in range(3)))

    @property
    def structured_pass(self) -> StructuredPass:
        """The steps grouped by kind and level, built (and checked) on first use."""
        if "_structured" not in self.__dict__:
            self._structured = StructuredPass(self._steps, self.controls)
        return self._structured

    def _pose_torch(self, Y: torch.Tensor) -> Pose:
        if not STRUCTURED or Y.shape[0] > STRUCTURED_MAX_POSES or torch.jit.is_tracing():
            return self.reference_pose(Y)
        if COMPILED and Y.shape[0] > 0:
            return self.compiled_pose(Y, COMPILED_POSES)
        return self.structured_pose(Y)

    def compiled_pose(self, Y: torch.Tensor, size: int) -> Pose:
        """The structured pass through its compiled graphs of ``size`` rows (built and
        compiled on first use per size and dtype; see :mod:`rigmap.rigs.engine.compiled`)."""
        passes = self.__dict__.setdefault("_compiled", {})
        if size not in passes:
            passes[size] = CompiledPass(self, size)
        return Pose(*passes[size](Y))

    def structured_pose(self, Y: torch.Tensor) -> Pose:
        """The pass by structure (:attr:`structured_pass`), whatever the batch size."""
        return self._pose_of(self.structured_pass.run(Y))

    def reference_pose(self, Y: torch.Tensor) -> Pose:
        """The step-by-step pass (each step once per instance, in the order built): the
        reference the structured pass is tested against."""
        ctx = EvalContext(Y)
        for step in self._steps:
            step(ctx)
        return self._pose_of(ctx)

    def _pose_of(self, ctx: EvalContext) -> Pose:
        missing = [j for j in self.joint_names if j not in ctx.xf]
        if missing:
            raise RuntimeError(f"rig {self.name!r}: no step wrote joints {missing[:5]}")
        world = torch.stack([ctx.xf[j].t for j in self.joint_names], dim=1)
        cog = ctx.xf[self._cog]
        return Pose(world - cog.t[:, None, :], cog.t, cog.R)

    def generic_trace(self, dtype: torch.dtype = torch.float64):
        """The trace that replays batches of any size (``GENERIC_TRACE``), or None.

        Recorded on ``GENERIC_TRACE_SIZE`` poses and checked once per dtype against the
        eager pass on 5 random poses across the soft ranges; a rig whose trace fails
        that (a step that bakes the batch size in) gets None, and the padded per-size
        traces serve it instead.
        """
        if not GENERIC_TRACE:
            return None
        cache = self.__dict__.setdefault("_generic_traces", {})
        if dtype not in cache:
            trace = self.traced_pose(GENERIC_TRACE_SIZE, dtype)
            cache[dtype] = trace if self._replays_other_sizes(trace, dtype) else None
        return cache[dtype]

    def _replays_other_sizes(self, trace, dtype: torch.dtype) -> bool:
        rng = np.random.default_rng(0)
        used = self.controls.used_indices
        Y = np.repeat(self.controls.defaults[None], 5, axis=0)
        lower, upper = self.controls.lower[used], self.controls.upper[used]
        Y[:, used] = rng.uniform(lower, upper, (5, len(used)))
        Yt = torch.from_numpy(Y).to(dtype)
        tolerance = 1e-9 if dtype == torch.float64 else 1e-3
        with torch.no_grad():
            try:
                got = trace(Yt)
            except RuntimeError:
                return False
            want = self._pose_torch(Yt)
        return all(
            g.shape == w.shape and bool(torch.allclose(g, w, rtol=0, atol=tolerance))
            for g, w in zip(got, (want.positions, want.cog, want.cog_rotation), strict=True)
        )

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
                traced = torch.jit.trace(pose_tuple, (example,), check_trace=False)
                for _ in range(JIT_WARMUP_CALLS):
                    traced(example)
                cache[key] = traced
        return cache[key]

    def world_transforms(self, Y) -> dict:
        """Every named world transform of one evaluation (controls, joints); for tests."""
        Y, _ = self._check_controls(Y)
        Yt = Y if _is_torch(Y) else torch.as_tensor(Y)
        ctx = EvalContext(Yt)
        for step in self._steps:
            step(ctx)
        return ctx.xf
