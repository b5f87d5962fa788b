"""``rigmap reproduce``: compose the experiment into params.yaml, then ``dvc repro`` with progress.

1. ``params.yaml`` is composed from ``conf/`` and the overrides (``experiment=paper``,
   ``budget.samples=20000`` ...) exactly as ``dvc exp run -S`` would compose it
   (:mod:`rigmap.app.params`); it is rewritten only when it changes.
2. ``dvc repro [STAGE ...]`` runs with the directory of the running Python first on
   ``PATH``, so every stage's ``python`` is the project's virtual environment.
   DVC's output is streamed as it comes, and a ``stage k/n`` line is printed when
   each stage starts (``n``: the stages DVC reports changed plus everything
   downstream of them — an upper bound, as DVC skips a stage whose inputs came out
   unchanged).
   Before it, a preflight (:mod:`rigmap.preflight`) checks in seconds what the stages
   will need: the Blender environment, the tracking server, writable output folders.
3. ``--jobs N`` (``make reproduce`` uses 2): the pending stages run side by side instead,
   each as its own ``dvc repro --single-item`` (:mod:`rigmap.stage_jobs`); the stages that
   time methods run alone, so their frames per second are not shared with another stage.
4. At the end it prints where ``index.html`` is.

Parameter values are checked before params.yaml is written (:mod:`rigmap.params_checks`),
and a dry run killed by SIGTERM, SIGHUP or Ctrl-C still puts the old params.yaml back.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from rigmap.app.params import (
    ParamsError,
    check_overrides,
    project_root,
    reaching_stages,
    write_params,
)
from rigmap.preflight import check_pipeline_needs
from rigmap.stage_jobs import families_marked, plan_stages, run_side_by_side
from rigmap.store import write_text_atomic
from rigmap.store.layout import Layout
from rigmap.store.pipeline_files import StageFamily, family_of, short_name, stage_families

# how DVC says a stage starts, or is restored from its run cache instead of running
STAGE_STARTS = (
    (re.compile(r"Running stage '([^']+)'"), ""),
    (re.compile(r"Stage '([^']+)' is cached - skipping run"), " (cached: outputs restored)"),
)
PREFIX = "[rigmap reproduce]"

#: Ask torch's MKL (BLAS) and ATen kernels for their AVX2 code paths, so that machines
#: which honour it round float32 training alike (another MKL path changed the quick
#: network's predictions by 2.6e-6 after 8 epochs, which refinement grows into per-cent
#: differences). Measured: MKL on AMD EPYC (Zen 5) ignores MKL_CBWR=AVX2 (mkl_cbwr_get
#: reports AUTO); MKL_CBWR=COMPATIBLE pins it but costs 3.4x per matrix product, so network
#: rows may still differ by 1-4 % across such hosts. A value already in the environment wins.
CPU_CODE_PATHS = {"MKL_CBWR": "AVX2", "ATEN_CPU_CAPABILITY": "avx2"}
#: One thread per stage in torch's and numpy's pools (OpenMP, MKL, OpenBLAS): ``--jobs``
#: runs stages side by side, and a stage's two threads then wait on each other behind the
#: other stage (measured beside a second job on this 2-core machine, session 39: the
#: joint-space fit's 54 000 posed draws 28 s on two threads, 3.4 s on one; a GMM supersample
#: stage 20.5 s against 6.9 s). Networks, refinement and tuning pinned one thread already;
#: this pins the rest, and makes a stage's arithmetic the same on any core count. If the
#: user set any of the three, none is set (torch takes the smallest).
STAGE_THREADS = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


@dataclass(frozen=True)
class ReproducePlan:
    """Everything a run needs, decided before anything is written or started."""

    project: Path
    overrides: tuple[str, ...]
    command: tuple[str, ...]
    env: dict[str, str]
    dry: bool
    params_only: bool = False
    jobs: int = 1
    keep_going: bool = False

    @property
    def count_stages(self) -> bool:
        return not self.dry

    @property
    def bin_dir(self) -> str:
        return self.env["PATH"].split(os.pathsep, 1)[0]


def plan_reproduce(
    overrides: Sequence[str] = (),
    *,
    targets: Sequence[str] = (),
    project: str | Path | None = None,
    dry: bool = False,
    force: bool = False,
    keep_going: bool = False,
    params_only: bool = False,
    jobs: int = 1,
    python: str | Path | None = None,
    environ: dict[str, str] | None = None,
) -> ReproducePlan:
    """Check the arguments and build the ``dvc repro`` command and its environment.

    ``params_only``: write params.yaml and stop (for ``dvc repro`` / ``dvc exp run`` by hand).
    ``jobs``: run up to this many independent stages at once (:mod:`rigmap.stage_jobs`).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ParamsError(f"--jobs {jobs!r}: expected a whole number of stages at a time, >= 1")
    root = project_root(project)
    overrides = tuple(check_overrides(overrides, Layout.project_conf(root)))
    for target in targets:
        if not target or target.startswith("-") or "=" in target:
            raise ParamsError(
                f"--target {target!r}: expected a stage name from dvc.yaml (e.g. report, "
                "fit_nn, evaluate@quadruped-methods)"
            )
    environ = dict(os.environ if environ is None else environ)
    bin_dir = str(Path(python or sys.executable).parent)
    path = os.pathsep.join([bin_dir, *[p for p in environ.get("PATH", "").split(os.pathsep) if p]])
    environ["PATH"] = path
    for name, value in CPU_CODE_PATHS.items():
        environ.setdefault(name, value)
    if not any(name in environ for name in STAGE_THREADS):  # torch reads all three
        environ.update(STAGE_THREADS)
    dvc = shutil.which("dvc", path=path)
    if dvc is None and params_only:
        dvc = "dvc"
    elif dvc is None:
        raise ParamsError(
            f"dvc not found on PATH (looked first in {bin_dir}); install the project "
            "(`make setup`, it brings dvc) or put dvc on PATH"
        )
    families = stage_families(root) if targets else {}
    command = [dvc, "repro", *(dvc_target(families, target) for target in targets)]
    if dry:
        command.append("--dry")
    if force:
        command.append("--force")
    if keep_going:
        command.append("--keep-going")
    return ReproducePlan(
        root, overrides, tuple(command), environ, dry, params_only, jobs, keep_going
    )


def count_stages(plan: ReproducePlan) -> int | None:
    """How many stages ``dvc repro`` may run: changed ones and everything downstream of them.

    From ``dvc status --json`` and ``dvc dag --dot`` (``dvc repro --dry`` cannot tell on a
    fresh clone: it stops at the first stage whose inputs do not exist yet). Restricted to
    the targets and what they depend on; ``None`` when DVC cannot say.
    """
    found = pending_stages(plan)
    return None if found is None else len(found[0])


def pending_stages(
    plan: ReproducePlan,
) -> tuple[set[str], list[tuple[str, str]], list[str]] | None:
    """The stages that may run (as :func:`count_stages` counts them), DVC's edges and nodes."""
    dvc = plan.command[0]
    targets = [short_name(c) for c in plan.command[2:] if not c.startswith("-")]
    force = "--force" in plan.command
    try:
        # both questions at once: each DVC start-up costs a second or two
        outputs = _dvc_outputs(
            [[dvc, "dag", "--dot"], *([] if force else [[dvc, "status", "--json"]])], plan
        )
        dag = outputs[0]
        nodes = [short_name(n) for n in _DOT_NODE.findall(dag)]
        edges = [(short_name(a), short_name(b)) for a, b in _DOT_EDGE.findall(dag)]
        changed = set(nodes) if force else {short_name(n) for n in json.loads(outputs[1])}
    except (OSError, ValueError, subprocess.CalledProcessError):
        return None
    downstream = {a: set() for a in nodes}
    upstream = {a: set() for a in nodes}
    for a, b in edges:
        downstream.setdefault(a, set()).add(b)
        upstream.setdefault(b, set()).add(a)
    may_run = _closure(changed & set(nodes), downstream)
    if targets:
        scope = _closure({t for t in targets if t in nodes}, upstream)
        if len(scope) == 0:
            return None  # a target DVC names differently (a dvc.yaml path, a glob)
        may_run &= scope
    return may_run, edges, nodes


_DOT_NODE = re.compile(r'^"([^"]+)";$', re.MULTILINE)
_DOT_EDGE = re.compile(r'^"([^"]+)" -> "([^"]+)";$', re.MULTILINE)


def dvc_target(families: Mapping[str, StageFamily], target: str) -> str:
    """A stage or family name as DVC addresses it: ``stages/<family>/dvc.yaml:<name>`` when
    its family lives in a stage file (:mod:`rigmap.store.pipeline_files`); else unchanged
    (an address already, or a root stage). A matrix key may hold a colon itself
    (``animate_blender@blend_file:hero``), so an address is told by its ``.yaml:``."""
    found = families.get(family_of(target)) if short_name(target) == target else None
    return target if found is None else found.address(target)


def _closure(start: set[str], links: dict[str, set[str]]) -> set[str]:
    seen, todo = set(start), list(start)
    while todo:
        for other in links.get(todo.pop(), ()):
            if other not in seen:
                seen.add(other)
                todo.append(other)
    return seen


def _dvc_outputs(commands: list[list[str]], plan: ReproducePlan) -> list[str]:
    """Run the commands side by side; their standard outputs (an error if one fails)."""
    running = [
        subprocess.Popen(
            command,
            cwd=plan.project,
            env=plan.env,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        for command in commands
    ]
    outputs = []
    for command, process in zip(commands, running, strict=True):
        stdout, _ = process.communicate()
        if process.returncode != 0:
            raise subprocess.CalledProcessError(process.returncode, command)
        outputs.append(stdout)
    return outputs


class Interrupted(SystemExit):
    """SIGTERM or SIGHUP arrived; unwinds like Ctrl-C (so params.yaml is restored), exit 128+n."""


@contextmanager
def _signals_unwind() -> Iterator[None]:
    """SIGTERM/SIGHUP raise ``Interrupted`` in the main thread, so ``finally`` blocks run."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def unwind(signum: int, frame: object) -> None:
        raise Interrupted(128 + signum)

    previous = {sig: signal.signal(sig, unwind) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def run_reproduce(plan: ReproducePlan, *, out: TextIO | None = None) -> int:
    """Write params.yaml, check what the run needs, run ``dvc repro`` streaming; DVC's exit code.

    params.yaml is written atomically; a dry run (or a run stopped by the preflight, a
    signal or Ctrl-C before ``dvc repro`` started) puts the previous file back.
    """
    out = out or sys.stdout
    params_file = plan.project / "params.yaml"
    with _signals_unwind():
        before = params_file.read_text(encoding="utf-8") if params_file.is_file() else None
        update = write_params(plan.project, plan.overrides)
        keep = False
        try:
            if not plan.dry and not plan.params_only:
                for line in check_pipeline_needs(plan.project, update.params, plan.env):
                    print(f"{PREFIX} preflight {line}", file=out, flush=True)
            keep = not plan.dry
            return _run(plan, update, out)
        finally:
            if update.changed and not keep:  # the workspace is left as it was
                if before is None:
                    params_file.unlink(missing_ok=True)
                else:
                    write_text_atomic(params_file, before)


def _run(plan: ReproducePlan, update, out: TextIO) -> int:
    state = "updated" if update.changed else "unchanged"
    chosen = " ".join(plan.overrides) or "(defaults of conf/config.yaml)"
    print(f"{PREFIX} params.yaml {state}: {chosen}", file=out, flush=True)
    if update.differs_from_defaults:
        reached = reaching_stages(update.differs_from_defaults, plan.project / "dvc.yaml")
        print(
            f"{PREFIX} differs from the defaults: {', '.join(update.differs_from_defaults)}",
            file=out,
        )
        if not reached:
            print(
                f"{PREFIX} warning: no stage in dvc.yaml interpolates any of these values "
                "(KEY=@NAME in its cmd, or ${...}), so they change nothing the pipeline runs",
                file=out,
            )
    if plan.params_only:
        print(f"{PREFIX} wrote {update.path}; run `dvc repro` or `dvc exp run` next", file=out)
        return 0
    total = count_stages(plan) if plan.count_stages else None
    if total is not None:
        print(f"{PREFIX} {total} stage(s) changed or downstream of a change", file=out, flush=True)
    print(f"{PREFIX} {' '.join(plan.command[1:])} (PATH starts with {plan.bin_dir})", file=out)
    out.flush()
    if plan.jobs > 1 and not plan.dry:
        code = _run_side_by_side(plan, out)
    else:
        code = _stream(plan, out, total)
    index = plan.project / Layout.from_paths(update.params.get("paths")).index_page()
    if code != 0:
        print(f"{PREFIX} dvc repro failed (exit code {code})", file=out)
    elif index.is_file():
        print(f"{PREFIX} report: {index}", file=out)
    else:
        print(f"{PREFIX} done; no report yet at {index} (the report stage did not run)", file=out)
    out.flush()
    return code


def _stream(plan: ReproducePlan, out: TextIO, total: int | None) -> int:
    """Pass DVC's output through as it arrives; announce each stage as it starts."""
    process = subprocess.Popen(
        plan.command,
        cwd=plan.project,
        env=plan.env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    assert process.stdout is not None
    announced: list[str] = []
    clock = StageClock()
    pending = ""
    try:
        while chunk := process.stdout.read1(4096):
            text = chunk.decode("utf-8", errors="replace")
            out.write(text)
            pending += text
            *complete, pending = re.split(r"[\r\n]", pending)
            for line in complete:
                for pattern, remark in STAGE_STARTS:
                    match = pattern.search(line)
                    if match and match.group(1) not in announced:
                        announced.append(match.group(1))
                        of = f"/{total}" if total else ""
                        took = clock.start(match.group(1))
                        out.write(
                            f"{PREFIX} stage {len(announced)}{of}: {match.group(1)}{remark}{took}\n"
                        )
            out.flush()
    except BaseException:  # Ctrl-C, SIGTERM (Interrupted), a broken pipe: DVC stops too
        process.terminate()
        process.wait()
        raise
    code = process.wait()
    clock.stop()
    out.write(clock.summary())
    return code


def _run_side_by_side(plan: ReproducePlan, out: TextIO) -> int:
    """``--jobs N``: the pending stages as separate single-stage ``dvc repro`` processes."""
    found = pending_stages(plan)
    if found is None:
        print(f"{PREFIX} DVC cannot list the pending stages; running them in turn", file=out)
        return _stream(plan, out, None)
    pending, edges, nodes = found
    families = stage_families(plan.project)
    alone, early = (families_marked(families, key) for key in ("runs_alone", "starts_early"))
    stages = plan_stages(pending, edges, nodes, alone, early)
    alone_note = f", {len(stages.alone)} of them alone" if stages.alone else ""
    print(
        f"{PREFIX} {len(stages.order)} stage(s), up to {plan.jobs} at a time{alone_note}",
        file=out,
        flush=True,
    )
    dvc, force = plan.command[0], ["--force"] if "--force" in plan.command else []
    clock = StageClock()
    began = time.perf_counter()
    code = run_side_by_side(
        stages,
        lambda stage: [
            dvc,
            "--wait-for-lock",
            "repro",
            "--single-item",
            *force,
            dvc_target(families, stage),
        ],
        jobs=plan.jobs,
        cwd=plan.project,
        env=plan.env,
        out=out,
        keep_going=plan.keep_going,
        on_finish=clock.record,
        prefix=PREFIX,
    )
    out.write(clock.summary(wall_seconds=time.perf_counter() - began))
    return code


class StageClock:
    """Wall time per stage, from one stage's start to the next one's (DVC runs them in turn).

    DVC prints no stage times; the summary tells where a run's time went (the
    slowest stages and each stage family: ``fit_nn@quadruped-gmm`` is ``fit_nn``).
    """

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._current: tuple[str, float] | None = None

    def start(self, stage: str) -> str:
        """Start timing ``stage``; returns the note on the previous one (``""`` for the first)."""
        previous = self.stop()
        self._current = (stage, time.perf_counter())
        return f" (previous took {previous:.1f} s)" if previous is not None else ""

    def stop(self) -> float | None:
        if self._current is None:
            return None
        stage, began = self._current
        self._current = None
        self.seconds[stage] = time.perf_counter() - began
        return self.seconds[stage]

    def record(self, stage: str, seconds: float) -> None:
        """A stage timed elsewhere (``--jobs``: each runs in its own process)."""
        self.seconds[stage] = seconds

    def summary(self, slowest: int = 10, wall_seconds: float | None = None) -> str:
        if not self.seconds:
            return ""
        families: dict[str, float] = {}
        for stage, seconds in self.seconds.items():
            family = stage.split("@", 1)[0]
            families[family] = families.get(family, 0.0) + seconds
        total = sum(self.seconds.values())
        wall = "" if wall_seconds is None else f" of stage time in {wall_seconds:.0f} s wall"
        lines = [f"{PREFIX} {len(self.seconds)} stage(s) ran in {total:.0f} s{wall}; slowest:"]
        for stage, seconds in sorted(self.seconds.items(), key=lambda kv: -kv[1])[:slowest]:
            lines.append(f"{PREFIX}   {seconds:7.1f} s  {stage}")
        lines.append(f"{PREFIX} by stage family:")
        for family, seconds in sorted(families.items(), key=lambda kv: -kv[1]):
            count = sum(1 for stage in self.seconds if stage.split("@", 1)[0] == family)
            lines.append(f"{PREFIX}   {seconds:7.1f} s  {family} ({count})")
        return "\n".join(lines) + "\n"
