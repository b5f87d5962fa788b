"""The structured pass compiled by inductor: one fused forward and backward per batch size.

The structured pass (:mod:`rigmap.rigs.engine.structured`) still runs about 2 600 small
torch operations a pass and as many autograd nodes, each costing more in overhead than in
arithmetic. Here the pass is recorded once per batch size and dtype as an aten graph
(``make_fx``: it runs the Python once, the closures' constants becoming graph constants,
so the rig's dict-based steps need no support from dynamo), and that graph is compiled by
``torch.compile`` (inductor, C++ kernels): the elementwise chains fuse and AOTAutograd
writes one backward graph, so a step pays a few dozen kernels instead of thousands of ops.

Valid because no rig step branches on control values (the TorchScript traces rely on the
same; checked against the reference in ``tests/test_rig_compiled.py``). The cost is the
compile: about 85 s per rig, dtype and size on a cold cache on this project's 2-core
machines, about 10 s (4 s recording, the rest loading) once inductor's on-disk cache holds
it (ours, session 38). Processes that would compile the same graph at once take turns
(:func:`_compile_turn`): the second then loads the first's result from the cache instead of
compiling it again beside it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

import torch
from filelock import FileLock
from torch.fx.experimental.proxy_tensor import make_fx

#: torch.compile's backend (ours: inductor fuses the pass; "aot_eager" only removes Python)
BACKEND = "inductor"
#: batched products whose inner size is at most this become broadcast products and sums
#: before compiling (ours: the rig's 3 x 3 and 3 x 1 products; inductor fuses those into
#: its loops, where a ``bmm`` stays an external call of ~13 µs each); 0 keeps every ``bmm``
ELEMENTWISE_PRODUCTS = 4
#: inductor's C++ options (ours, session 38, quadruped forward+backward at 128 float32 rows,
#: one thread, same run): scalar kernels (``simdlen`` 1) compile in 85 s against the
#: vectorised ones' 142 s, and run faster at these row counts (6.6 against 7.9 ms)
INDUCTOR_OPTIONS = {"cpp.simdlen": 1}


def elementwise_products(graph: torch.fx.GraphModule, largest: int) -> int:
    """Rewrite ``graph``'s ``bmm`` nodes with inner size at most ``largest`` as
    ``(A[:, :, :, None] * B[:, None]).sum(2)``: the same sums of products (summed in
    another order, so equal to rounding). Returns how many were rewritten."""
    aten, count = torch.ops.aten, 0
    for node in list(graph.graph.nodes):
        if node.target is not aten.bmm.default:
            continue
        a, b = node.args
        if a.meta["val"].shape[-1] > largest:
            continue
        with graph.graph.inserting_before(node):
            left = graph.graph.call_function(aten.unsqueeze.default, (a, 3))
            right = graph.graph.call_function(aten.unsqueeze.default, (b, 1))
            product = graph.graph.call_function(aten.mul.Tensor, (left, right))
            summed = graph.graph.call_function(aten.sum.dim_IntList, (product, [2]))
        summed.meta = dict(node.meta)
        node.replace_all_uses_with(summed)
        graph.graph.erase_node(node)
        count += 1
    graph.recompile()
    return count


def _compile_turn(graph: torch.fx.GraphModule, rig_name: str) -> FileLock:
    """A lock in inductor's cache folder named by the recorded graph's code: one process at
    a time compiles (or loads) a given graph."""
    from torch._inductor.runtime.cache_dir_utils import cache_dir

    digest = hashlib.sha256(graph.code.encode()).hexdigest()[:16]
    folder = Path(cache_dir()) / "rigmap_locks"
    folder.mkdir(parents=True, exist_ok=True)
    return FileLock(str(folder / f"{rig_name}-{digest}.lock"))


def _first_call_in_turn(compiled: Callable, recorded: torch.fx.GraphModule, rig_name: str):
    """``compiled``, its first call (where inductor compiles, forward and backward) taken
    under :func:`_compile_turn`'s lock."""
    state = {"first": True}

    def call(Y: torch.Tensor):
        if not state["first"]:
            return compiled(Y)
        with _compile_turn(recorded, rig_name):
            out = compiled(Y)
            if Y.requires_grad and torch.is_grad_enabled():  # the backward compiles lazily
                torch.autograd.grad(sum(o.sum() for o in out), Y, retain_graph=True)
        state["first"] = False
        return out

    return call


class CompiledPass:
    """``Y (n, C) -> (positions, cog, cog_rotation)`` through compiled graphs of ``size`` rows.

    A batch of fewer rows is padded with default controls to ``size`` (rows do not mix, so
    its rows' values and gradients are the unpadded ones); a larger batch runs in chunks.
    """

    def __init__(self, rig, size: int):
        if size < 1:
            raise ValueError(f"compiled pass: size must be at least 1, got {size}")
        self._rig, self.size = rig, int(size)
        self._graphs: dict[torch.dtype, Callable] = {}

    def graph(self, dtype: torch.dtype) -> Callable:
        """The compiled pass for ``size`` rows of ``dtype`` (recorded on first use; inductor
        compiles it on its first call)."""
        if dtype not in self._graphs:
            rig = self._rig
            example = torch.as_tensor(rig.controls.defaults, dtype=dtype).expand(self.size, -1)
            with torch.no_grad():  # the pass's lazy per-size tables built before recording,
                rig.structured_pose(example.clone())  # so every process records one graph

            def pose_tuple(Y: torch.Tensor):
                pose = rig.structured_pose(Y)
                return pose.positions, pose.cog, pose.cog_rotation

            recorded = make_fx(pose_tuple)(example.clone())
            if ELEMENTWISE_PRODUCTS:
                elementwise_products(recorded, ELEMENTWISE_PRODUCTS)
            compiled = torch.compile(
                recorded, backend=BACKEND, dynamic=False, fullgraph=True, options=INDUCTOR_OPTIONS
            )
            self._graphs[dtype] = _first_call_in_turn(compiled, recorded, rig.name)
        return self._graphs[dtype]

    def __call__(self, Y: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        parts = [self._padded(Y[i : i + self.size]) for i in range(0, len(Y), self.size)]
        if len(parts) == 1:
            return parts[0]
        return tuple(torch.cat([p[k] for p in parts]) for k in range(3))

    def _padded(self, Y: torch.Tensor):
        n = len(Y)
        if n < self.size:
            defaults = torch.as_tensor(self._rig.controls.defaults, dtype=Y.dtype)
            Y = torch.cat([Y, defaults.expand(self.size - n, -1)])
        out = self.graph(Y.dtype)(Y)
        return out if n == self.size else tuple(o[:n] for o in out)
