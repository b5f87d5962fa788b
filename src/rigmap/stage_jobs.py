"""Pending DVC stages run side by side: ``rigmap reproduce --jobs N``.

``dvc repro`` runs one stage at a time. DVC releases its repository lock while a stage's
command runs, and documents running independent stages as separate ``dvc repro``
processes; this module is the scheduler DVC lacks for that: each stage runs as
``dvc --wait-for-lock repro --single-item STAGE`` once every pending stage upstream of
it has finished, at most ``jobs`` at once. Stages whose family carries
``meta: {runs_alone: true}`` in ``dvc.yaml`` (the ones that time methods: a frames-per-
second figure must not share the CPUs with another stage) run with nothing beside them.
Stages marked ``meta: {starts_early: true}`` (the long ones, whose chains set the wall
time), and the pending stages upstream of them, take a free slot before any other ready
stage: a long chain waiting on a short stage that other ready stages keep from starting
starts late (session 39: the biped's joint-space fit waited four minutes for its poses).
"""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from rigmap.store.pipeline_files import StageFamily, family_of


@dataclass(frozen=True)
class StagePlan:
    """The stages to run in DVC's order and, for each, the pending stages it waits for."""

    order: tuple[str, ...]
    waits_for: Mapping[str, frozenset[str]]
    alone: frozenset[str] = frozenset()
    early: frozenset[str] = frozenset()

    def start_order(self) -> list[str]:
        """The order a free slot is offered in: the early stages first, each group in
        :attr:`order` (a stage still starts only once the stages it waits for are done)."""
        return sorted(self.order, key=lambda stage: stage not in self.early)


def families_marked(families: Mapping[str, StageFamily], key: str) -> frozenset[str]:
    """The stage families (:func:`~rigmap.store.pipeline_files.stage_families`, read once
    by the caller) marked ``meta: {<key>: true}``."""
    return frozenset(
        name for name, found in families.items() if (found.body.get("meta") or {}).get(key) is True
    )


def plan_stages(
    pending: set[str],
    edges: Sequence[tuple[str, str]],
    nodes_in_order: Sequence[str],
    alone_families: frozenset[str] = frozenset(),
    early_families: frozenset[str] = frozenset(),
) -> StagePlan:
    """Order ``pending`` so every stage comes after the pending stages it depends on.

    ``edges`` are DVC's ``(upstream, downstream)`` pairs (``dvc dag --dot``); a stage waits
    for a pending stage anywhere upstream of it, through stages that need not run. The
    plan's early stages are those of ``early_families`` and every pending stage they wait for.
    """
    upstream: dict[str, set[str]] = {}
    for a, b in edges:
        upstream.setdefault(b, set()).add(a)
    waits_for = {}
    for stage in pending:
        seen, todo = set(), [stage]
        while todo:
            for other in upstream.get(todo.pop(), ()):
                if other not in seen:
                    seen.add(other)
                    todo.append(other)
        waits_for[stage] = frozenset(seen & pending)
    order, done = [], set()
    rank = {name: i for i, name in enumerate(nodes_in_order)}
    remaining = sorted(pending, key=lambda s: (rank.get(s, len(rank)), s))
    while remaining:
        ready = [s for s in remaining if waits_for[s] <= done]
        if not ready:
            raise ValueError(f"the DVC graph has a cycle among {sorted(remaining)}")
        order.extend(ready)
        done.update(ready)
        remaining = [s for s in remaining if s not in done]
    alone = frozenset(s for s in pending if family_of(s) in alone_families)
    marked = {s for s in pending if family_of(s) in early_families}
    early = frozenset(marked.union(*(waits_for[s] for s in marked)))
    return StagePlan(tuple(order), waits_for, alone, early)


@dataclass
class _Running:
    process: subprocess.Popen
    reader: threading.Thread
    began: float


def run_side_by_side(
    plan: StagePlan,
    command_for: Callable[[str], Sequence[str]],
    *,
    jobs: int,
    cwd: Path,
    env: Mapping[str, str],
    out: TextIO,
    keep_going: bool = False,
    on_finish: Callable[[str, float], None] | None = None,
    prefix: str = "",
) -> int:
    """Run the plan's stages, ``jobs`` at a time; 0, or the first failing stage's exit code.

    A stage's output is printed line by line behind ``[stage]`` (progress bars only in
    their last state: several interleaved bars are unreadable). After a failure no new
    stage starts, unless ``keep_going``: then the stages that do not depend on a failed
    one still run. Ctrl-C or a signal stops every running stage.
    """
    if jobs < 1:
        raise ValueError(f"--jobs {jobs}: need at least 1 stage at a time")
    printing = threading.Lock()
    total = len(plan.order)
    started: list[str] = []
    finished: set[str] = set()
    failed: dict[str, int] = {}
    running: dict[str, _Running] = {}

    def say(text: str) -> None:
        with printing:
            out.write(text + "\n")
            out.flush()

    def blocked(stage: str) -> bool:  # waits_for is transitive: a failure anywhere upstream
        return not plan.waits_for[stage].isdisjoint(failed)

    def startable(stage: str) -> bool:
        if stage in started or not plan.waits_for[stage] <= finished:
            return False
        if running and (stage in plan.alone or any(s in plan.alone for s in running)):
            return False
        return len(running) < jobs

    def start(stage: str) -> None:
        running[stage] = _launch(command_for(stage), cwd, env, stage, say)
        started.append(stage)
        side = f", beside {', '.join(s for s in running if s != stage)}" if len(running) > 1 else ""
        say(f"{prefix} stage {len(started)}/{total} started: {stage}{side}")

    offer_order = plan.start_order()
    try:
        while True:
            if not failed or keep_going:
                for stage in offer_order:
                    if stage not in started and not blocked(stage) and startable(stage):
                        start(stage)
            if not running:
                break
            time.sleep(0.2)
            for stage, code, seconds in _collect_finished(running):
                if code == 0:
                    finished.add(stage)
                    say(f"{prefix} stage done: {stage} ({seconds:.1f} s)")
                    if on_finish is not None:
                        on_finish(stage, seconds)
                else:
                    failed[stage] = code
                    say(f"{prefix} stage FAILED: {stage} (exit code {code}, {seconds:.1f} s)")
    except BaseException:  # Ctrl-C, a signal: no stage outlives the run
        for entry in running.values():
            entry.process.terminate()
        for entry in running.values():
            entry.process.wait()
        raise
    skipped = [s for s in plan.order if s not in started]
    if failed:
        names = ", ".join(failed)
        say(f"{prefix} failed: {names}; not run: {len(skipped)} stage(s)")
        return next(iter(failed.values()))
    return 0


def _launch(
    command: Sequence[str], cwd: Path, env: Mapping[str, str], stage: str, say: Callable
) -> _Running:
    """Start one stage's process and the thread that prints its output."""
    process = subprocess.Popen(
        list(command), cwd=cwd, env=dict(env), stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )
    reader = threading.Thread(target=_relay, args=(process, stage, say), daemon=True)
    reader.start()
    return _Running(process, reader, time.perf_counter())


def _collect_finished(running: dict[str, _Running]) -> list[tuple[str, int, float]]:
    """The stages whose process ended, taken out of ``running``: (stage, exit code, seconds)."""
    ended = []
    for stage, entry in list(running.items()):
        code = entry.process.poll()
        if code is None:
            continue
        entry.reader.join()  # the last lines are printed before the stage is called done
        ended.append((stage, code, time.perf_counter() - entry.began))
        del running[stage]
    return ended


def _relay(process: subprocess.Popen, stage: str, say: Callable[[str], None]) -> None:
    """Print a stage's output as ``[stage] line``; of a ``\\r``-redrawn line only the last."""
    assert process.stdout is not None
    for raw in process.stdout:
        text = raw.decode("utf-8", errors="replace").rstrip("\r\n")
        text = text.rsplit("\r", 1)[-1].rstrip()
        if text:
            say(f"[{stage}] {text}")
