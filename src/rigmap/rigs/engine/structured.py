"""A rig's steps evaluated by structure: every feature unit once for all its instances.

The reference pass (:meth:`TorchRig.reference_pose`) runs a rig's steps one after the
other, so a pass costs the sum of every unit's small torch operations (about 5 000 on the
quadruped). This pass groups the steps by kind and by depth instead, when the rig is
built:

- one recording evaluation logs what each step reads and writes (named world transforms,
  control objects' locals, control columns), in order;
- steps made by the same code with the same access pattern (the four limbs, the toes, the
  ears, the eyes, every control object under the same parent depth …) form a *group* when
  none depends on another; each step gets a *level* (one more than the levels of the
  steps it reads from), a group the highest level of its members;
- a group runs its unit's own code once on the instances *folded into the batch*
  (``K`` instances of ``N`` poses as ``K·N`` rows): the closure's per-instance constants
  (rest offsets, pivots, side signs) become ``(K·N, …)`` tensors, the named transforms it
  reads are concatenated and the ones it writes split back, so the arithmetic per row is
  the reference's and a group costs about one instance's operations;
- levels run in order, all groups of a level independent of each other.

Every group is checked against its members run one by one at build time (random controls
across the soft ranges, float64, ``GROUP_TOLERANCE``); a group that fails or raises is
split back into single steps, so any unit works, batched or not.
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable, Sequence

import numpy as np
import torch

from rigmap.rigs.engine import builder
from rigmap.rigs.engine.builder import Attribute, EvalContext, TransformControl
from rigmap.rigs.engine.transforms import Transform

#: a group must give its members' transforms to this (cm, float64) at build time (ours: the
#: folded arithmetic is the reference's row by row, so anything above rounding is a bug)
GROUP_TOLERANCE = 1e-10
#: poses of the build-time recording and group check (ours: small, any size would do)
CHECK_POSES = 3


class _Log(dict):
    """A dict of transforms that logs every read and write of one step."""

    def __init__(self, kind: str, events: list):
        super().__init__()
        self._kind, self.events = kind, events

    def __getitem__(self, key):
        self.events.append((f"{self._kind}_get", key))
        return super().__getitem__(key)

    def __setitem__(self, key, value):
        self.events.append((f"{self._kind}_set", key))
        super().__setitem__(key, value)

    def __contains__(self, key):
        self.events.append((f"{self._kind}_has", key))
        return super().__contains__(key)


class _RecordingContext(EvalContext):
    """An evaluation context that logs each step's accesses (``events``) as it runs."""

    def __init__(self, Y: torch.Tensor):
        super().__init__(Y)
        self.events: list = []
        self.xf = _Log("xf", self.events)
        self.local = _Log("local", self.events)

    def value(self, column: int) -> torch.Tensor:
        self.events.append(("value", column))
        return super().value(column)

    def values(self, columns: list[int]) -> torch.Tensor:
        self.events.append(("values", tuple(columns)))
        return super().values(columns)


def record(steps: Sequence[Callable], Y: torch.Tensor) -> tuple[list[list], _RecordingContext]:
    """Each step's access events, in order, and the context after the whole pass."""
    ctx = _RecordingContext(Y)
    logs = []
    for step in steps:
        ctx.events.clear()
        step(ctx)
        logs.append(list(ctx.events))
    return logs, ctx


class _Unfoldable(Exception):
    """Steps that cannot run as one group (different access patterns or constants)."""


class _Stacked:
    """One closure constant that differs between instances: its ``K`` values, stacked."""

    def __init__(self, values: list):
        self.array = np.stack([np.asarray(v, dtype=np.float64) for v in values])

    def rows(self, n, dtype: torch.dtype) -> torch.Tensor:
        """The values as ``(K·n, …)`` rows, instance by instance (the folded batch order).

        ``n`` may be a traced size: a TorchScript trace then replays any batch size.
        """
        k, rest = self.array.shape[0], self.array.shape[1:]
        base = torch.as_tensor(self.array, dtype=dtype)[:, None]
        return base.expand(k, n, *rest).reshape(k * n, *rest)


def _same(a, b) -> bool:
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b))
    try:
        return type(a) is type(b) and bool(a == b)
    except (ValueError, TypeError):  # containers of arrays compare elementwise
        return False


def _numeric(value) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, int | float | np.floating | np.integer | np.ndarray):
        return True
    return isinstance(value, tuple | list) and len(value) > 0 and all(map(_numeric, value))


def _fold(values: list, names: list[set]):
    """A closure constant of every instance -> a tree of kept values and :class:`_Stacked`.

    Names (strings that begin a name each instance reads or writes), attributes and control
    objects stay the first instance's: the folded context maps those to every instance's
    (:class:`_FoldedContext`). Other strings that differ (a bend axis) cannot be folded.
    """
    first = values[0]
    if all(_same(first, v) for v in values[1:]):
        return first
    if any(type(v) is not type(first) for v in values):
        raise _Unfoldable(f"constants of different types {type(first).__name__}")
    if isinstance(first, Attribute | TransformControl):
        return first
    if isinstance(first, str):
        if all(
            any(key.startswith(v) for key in keys) for v, keys in zip(values, names, strict=True)
        ):
            return first
        raise _Unfoldable(f"strings {first!r} and others differ")
    if _numeric(first):
        return _Stacked(values)
    if dataclasses.is_dataclass(first):
        fields = [f.name for f in dataclasses.fields(first) if f.init]
        return (
            "dataclass",
            first,
            {f: _fold([getattr(v, f) for v in values], names) for f in fields},
        )
    if isinstance(first, dict):  # keyed by names: the instances' entries pair up in order
        if any(len(v) != len(first) for v in values):
            raise _Unfoldable("dicts of different sizes")
        entries = [list(v.values()) for v in values]
        folded = [_fold([e[i] for e in entries], names) for i in range(len(first))]
        return ("dict", dict(zip(first, folded, strict=True)))
    if isinstance(first, list | tuple):
        if any(len(v) != len(first) for v in values):
            raise _Unfoldable("sequences of different lengths")
        items = [_fold([v[i] for v in values], names) for i in range(len(first))]
        return ("seq", type(first), items)
    if isinstance(first, types.FunctionType) and all(v.__code__ is first.__code__ for v in values):
        return first
    raise _Unfoldable(f"constants of type {type(first).__name__} differ")


def _rows(tree, n: int, dtype: torch.dtype):
    """A folded constant with every :class:`_Stacked` turned into its ``(K·n, …)`` rows."""
    if isinstance(tree, _Stacked):
        return tree.rows(n, dtype)
    if isinstance(tree, tuple) and tree and isinstance(tree[0], str):
        if tree[0] == "dataclass":
            _, first, fields = tree
            return dataclasses.replace(first, **{k: _rows(v, n, dtype) for k, v in fields.items()})
        if tree[0] == "dict":
            return {k: _rows(v, n, dtype) for k, v in tree[1].items()}
        if tree[0] == "seq":
            return tree[1](_rows(v, n, dtype) for v in tree[2])
    return tree


class _FoldedMap(dict):
    """Named transforms of ``K`` instances as ``K·n`` rows, keyed by the first's names.

    A read concatenates the instances' transforms; a write splits the rows back into
    each instance's name of the underlying context.
    """

    def __init__(self, base: dict, keys: dict):
        super().__init__()
        self._base, self._keys = base, keys

    def __missing__(self, key):
        parts = [self._base[k] for k in self._keys[key]]
        value = Transform(torch.cat([p.R for p in parts]), torch.cat([p.t for p in parts]))
        dict.__setitem__(self, key, value)
        return value

    def __setitem__(self, key, value):
        dict.__setitem__(self, key, value)
        names = self._keys[key]
        k = len(names)  # unbind, not split: a trace keeps the batch size a traced value
        Rs = value.R.reshape(k, -1, *value.R.shape[1:]).unbind(0)
        ts = value.t.reshape(k, -1, *value.t.shape[1:]).unbind(0)
        for name, R, t in zip(names, Rs, ts, strict=True):
            self._base[name] = Transform(R, t)

    def __contains__(self, key):
        return key in self._keys or dict.__contains__(self, key)


class _BlockLocals(dict):
    """The control objects' locals kept as the blocks they were computed in, each split into
    its controls' transforms by one ``unbind`` when first asked for (one gradient node for
    the block, where a view per control would each fill a zero tensor the block's size)."""

    def __init__(self, blocks: list[tuple[list[str], torch.Tensor, torch.Tensor]]):
        super().__init__()
        self._blocks = blocks
        self._rows: dict[int, tuple] = {}
        self._where = {
            name: (b, k) for b, (names, _, _) in enumerate(blocks) for k, name in enumerate(names)
        }

    def _block(self, b: int) -> tuple:
        if b not in self._rows:
            _, R, t = self._blocks[b]
            self._rows[b] = (R.unbind(0), t.unbind(0))
        return self._rows[b]

    def __missing__(self, name):
        b, k = self._where[name]
        Rs, ts = self._block(b)
        value = Transform(Rs[k], ts[k])
        dict.__setitem__(self, name, value)
        return value

    def __contains__(self, name):
        return name in self._where or dict.__contains__(self, name)


class _Locals:
    """The locals step of a rig, run so its blocks stay whole (:class:`_BlockLocals`)."""

    def __init__(self, step: Callable):
        self.step = step

    def __call__(self, ctx: EvalContext) -> None:
        if not builder.CONTROL_MAJOR_LOCALS:  # the other layout writes transforms directly
            self.step(ctx)
            return
        ctx.local = _BlockLocals(self.step.blocks(ctx))


def _alone(step: Callable) -> Callable:
    """A step run by itself (the locals step keeping its blocks whole)."""
    return _Locals(step) if hasattr(step, "blocks") else step


class _PassContext(EvalContext):
    """The pass's context: the control columns the steps read, taken from ``Y`` at once.

    One gather for the pass instead of one per column read, whose gradients would each
    fill a zero tensor the size of ``Y``; the same values.
    """

    def __init__(self, Y: torch.Tensor, columns: dict[int, int], index: torch.Tensor):
        super().__init__(Y)
        self._rows = Y.index_select(1, index).t().unbind(0) if len(index) else ()
        self._where = columns

    def value(self, column: int) -> torch.Tensor:
        where = self._where.get(column)
        return super().value(column) if where is None else self._rows[where]


class _FoldedContext:
    """What a group's folded step sees: ``K`` instances of ``n`` poses as ``K·n`` poses."""

    def __init__(self, ctx: EvalContext, group: _Group):
        n = ctx.n
        self.n, self.dtype = group.size * n, ctx.dtype
        self._ctx, self._Y, self._columns = ctx, ctx.Y, group.columns
        self.xf = _FoldedMap(ctx.xf, group.xf_keys)
        self.local = _FoldedMap(ctx.local, group.local_keys)

    def value(self, column: int) -> torch.Tensor:
        return torch.cat([self._ctx.value(c) for c in self._columns[column]])

    def values(self, columns: list[int]) -> torch.Tensor:
        index = np.array([self._columns[c] for c in columns])  # (m, K)
        picked = self._Y[:, torch.as_tensor(index.T.reshape(-1))]  # (n, K·m)
        m = len(columns)
        return picked.reshape(-1, index.shape[1], m).transpose(0, 1).reshape(-1, m)

    def const(self, array) -> torch.Tensor:
        if isinstance(array, torch.Tensor):
            return array
        return torch.as_tensor(np.asarray(array, dtype=np.float64), dtype=self.dtype)


def _key_maps(logs: list[list]) -> tuple[dict, dict, dict]:
    """First instance's names and columns -> every instance's, from aligned access logs."""
    kinds = [kind for kind, _ in logs[0]]
    if any([kind for kind, _ in log] != kinds for log in logs[1:]):
        raise _Unfoldable("access patterns differ")
    maps: dict[str, dict] = {"xf": {}, "local": {}, "column": {}}

    def put(space: str, key, keys: list) -> None:
        if maps[space].setdefault(key, keys) != keys:
            raise _Unfoldable(f"{key!r} stands for different {space} entries")

    for i, (kind, key) in enumerate(logs[0]):
        if kind == "value":
            put("column", key, [log[i][1] for log in logs])
        elif kind == "values":
            for j, column in enumerate(key):
                put("column", column, [log[i][1][j] for log in logs])
        else:
            put(kind.split("_")[0], key, [log[i][1] for log in logs])
    return maps["xf"], maps["local"], maps["column"]


class _Group:
    """``K`` steps made by the same code, run once on their instances folded into the batch."""

    def __init__(self, steps: list[Callable], logs: list[list]):
        self.steps = steps
        self.size = len(steps)
        self.xf_keys, self.local_keys, self.columns = _key_maps(logs)
        code = steps[0].__code__
        if any(s.__code__ is not code for s in steps) or not steps[0].__closure__:
            raise _Unfoldable("not one unit's closures")
        cells = [[c.cell_contents for c in s.__closure__] for s in steps]
        names = [{key for _, key in log if isinstance(key, str)} for log in logs]
        self._cells = [_fold([m[i] for m in cells], names) for i in range(len(cells[0]))]
        self._functions: dict = {}

    def _function(self, n, dtype: torch.dtype) -> Callable:
        """The step's code over folded constants for ``n`` poses, cached per size and dtype
        (not while tracing: the trace must compute the rows from its input's size)."""
        key = (n, dtype)
        tracing = torch.jit.is_tracing()
        if tracing or key not in self._functions:
            if len(self._functions) > 8:  # a few sizes recur; bound the cache all the same
                self._functions.clear()
            first = self.steps[0]
            closure = tuple(types.CellType(_rows(c, n, dtype)) for c in self._cells)
            function = types.FunctionType(
                first.__code__, first.__globals__, first.__name__, first.__defaults__, closure
            )
            if tracing:
                return function
            self._functions[key] = function
        return self._functions[key]

    def __call__(self, ctx: EvalContext) -> None:
        if ctx.n == 0:  # nothing to fold (and 0 rows cannot say which instance is which)
            for step in self.steps:
                step(ctx)
            return
        self._function(ctx.n, ctx.dtype)(_FoldedContext(ctx, self))


def _dependencies(logs: list[list]) -> list[set[int]]:
    """For each step, the earlier steps it must follow: those that wrote what it reads, and
    those that read or wrote what it writes (so a name written twice keeps its order)."""
    writer: dict = {}
    readers: dict = {}
    deps = []
    for i, log in enumerate(logs):
        mine = set()
        for kind, key in log:
            where = (kind.split("_")[0], key)
            if kind.endswith(("_get", "_has")):
                if where in writer:
                    mine.add(writer[where])
                readers.setdefault(where, set()).add(i)
            elif kind.endswith("_set"):
                mine |= readers.get(where, set())
                if where in writer:
                    mine.add(writer[where])
        mine.discard(i)
        deps.append(mine)
        for kind, key in log:
            if kind.endswith("_set"):
                writer[(kind.split("_")[0], key)] = i
                readers.pop((kind.split("_")[0], key), None)
    return deps


def _ancestors(deps: list[set[int]]) -> list[set[int]]:
    result: list[set[int]] = []
    for direct in deps:
        every = set(direct)
        for d in direct:
            every |= result[d]
        result.append(every)
    return result


def _candidate_groups(steps, logs, ancestors) -> list[list[int]]:
    """Steps with the same code and access pattern, split so no member depends on another."""
    by_kind: dict = {}
    for i, (step, log) in enumerate(zip(steps, logs, strict=True)):
        signature = (getattr(step, "__code__", id(step)), tuple(kind for kind, _ in log))
        by_kind.setdefault(signature, []).append(i)
    groups = []
    for members in by_kind.values():
        open_groups: list[list[int]] = []
        for i in members:
            home = next((g for g in open_groups if not any(j in ancestors[i] for j in g)), None)
            if home is None:
                open_groups.append([i])
            else:
                home.append(i)
        groups.extend(open_groups)
    return groups


def _foldable_parts(steps, logs, candidates: list[int]) -> list[list[int]]:
    """Candidates split greedily into groups whose constants fold (a thumb bends about
    another axis than the other fingers, so it goes alone)."""
    parts: list[list[int]] = []
    for i in candidates:
        for part in parts:
            try:
                _Group([steps[j] for j in [*part, i]], [logs[j] for j in [*part, i]])
            except _Unfoldable:
                continue
            part.append(i)
            break
        else:
            parts.append([i])
    return parts


def _levels(deps: list[set[int]], groups: list[list[int]]) -> list[int] | None:
    """Each step's level: above every step it reads from, equal across its group.

    None when the groups cannot all be levelled (two groups waiting on each other).
    """
    level = [0] * len(deps)
    group_of = {i: g for g, members in enumerate(groups) for i in members}
    for _ in range(len(deps) + 1):
        changed = False
        for i, direct in enumerate(deps):
            want = max((level[d] + 1 for d in direct), default=0)
            want = max(want, max(level[j] for j in groups[group_of[i]]))
            if want != level[i]:
                level[i], changed = want, True
        if not changed:
            return level
    return None


def check_controls(controls, n: int, seed: int = 0) -> np.ndarray:
    """``n`` random control vectors: defaults, used channels uniform over their soft ranges."""
    rng = np.random.default_rng(seed)
    used = controls.used_indices
    Y = np.repeat(controls.defaults[None], n, axis=0)
    Y[:, used] = rng.uniform(controls.lower[used], controls.upper[used], (n, len(used)))
    return Y


class StructuredPass:
    """A rig's steps as levels of groups (see the module's docstring); ``run(Y) -> ctx``."""

    def __init__(self, steps: Sequence[Callable], controls):
        steps = list(steps)
        Y = torch.as_tensor(check_controls(controls, CHECK_POSES), dtype=torch.float64)
        with torch.no_grad():
            logs, reference = record(steps, Y)
        deps = _dependencies(logs)
        read = sorted({key for log in logs for kind, key in log if kind == "value"})
        self._read = {column: i for i, column in enumerate(read)}
        self._read_index = torch.as_tensor(read, dtype=torch.long)
        groups, units = [], []
        for candidates in _candidate_groups(steps, logs, _ancestors(deps)):
            for members in _foldable_parts(steps, logs, candidates):
                unit = self._unit(steps, logs, members, reference)
                # members of a group that fails its check run one by one
                parts = [members] if unit is not None else [[i] for i in members]
                groups.extend(parts)
                alone = [_alone(steps[i]) for i in members]
                units.extend([unit] if unit is not None else alone)
        level = _levels(deps, groups)
        if level is None:  # levelling failed: every step alone, in the reference order
            groups, units = [[i] for i in range(len(steps))], [_alone(s) for s in steps]
            level = _levels(deps, groups)
        order = sorted(range(len(groups)), key=lambda g: (level[groups[g][0]], min(groups[g])))
        self.units = [units[g] for g in order]
        self.levels = [level[groups[g][0]] for g in order]
        self.group_sizes = [len(groups[g]) for g in order]

    @staticmethod
    def _unit(steps, logs, members: list[int], reference) -> _Group | None:
        """A checked group of these steps, or None (they run one by one)."""
        if len(members) < 2:
            return None
        group = _Group([steps[i] for i in members], [logs[i] for i in members])
        try:
            ctx = EvalContext(reference.Y)
            ctx.xf, ctx.local = dict(reference.xf), dict(reference.local)
            with torch.no_grad():
                group(ctx)
        except (RuntimeError, ValueError, TypeError, KeyError, IndexError):
            return None
        written = {key for i in members for kind, key in logs[i] if kind == "xf_set"}
        for key in written:
            got, want = ctx.xf[key], dict.__getitem__(reference.xf, key)
            for a, b in ((got.R, want.R), (got.t, want.t)):
                if a.shape != b.shape or not torch.allclose(a, b, rtol=0, atol=GROUP_TOLERANCE):
                    return None
        return group

    def run(self, Y: torch.Tensor) -> EvalContext:
        ctx = _PassContext(Y, self._read, self._read_index)
        for unit in self.units:
            unit(ctx)
        return ctx
