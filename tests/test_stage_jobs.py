"""``rigmap reproduce --jobs N`` on a real DVC project: order, overlap, running alone, failures."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rigmap.reproduce import ReproducePlan, _run_side_by_side, pending_stages
from rigmap.stage_jobs import plan_stages

BIN = Path(sys.executable).parent

# each stage appends "<name> start <t>" and "<name> end <t>" to log/<name>, sleeping between
STAGE = (
    "python -c \"import sys,time; n=sys.argv[1]; f=open('log/'+n,'w'); "
    "f.write('start %r\\n' % time.time()); f.flush(); time.sleep(float(sys.argv[2])); "
    "f.write('end %r\\n' % time.time()); open('out/'+n,'w').write(n)\" {name} {sleep}"
)


def _project(tmp_path: Path, fail: str | None = None) -> Path:
    """a and b are independent, c needs both, d needs nothing but runs alone, e needs c."""
    (tmp_path / "log").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / ".gitignore").write_text("")

    def stage(name: str, deps: list[str], sleep: float, alone: bool = False) -> str:
        cmd = "exit 3" if name == fail else STAGE.format(name=name, sleep=sleep)
        lines = [f"  {name}:", f"    cmd: {cmd}"]
        if alone:
            lines.append("    meta: {runs_alone: true}")
        if deps:
            lines.append(f"    deps: [{', '.join('out/' + d for d in deps)}]")
        lines.append(f"    outs: [out/{name}]")
        return "\n".join(lines)

    stages = [
        stage("a", [], 1.5),
        stage("b", [], 1.5),
        stage("c", ["a", "b"], 0.2),
        stage("d", [], 0.5, alone=True),
        stage("e", ["c"], 0.2),
    ]
    (tmp_path / "dvc.yaml").write_text("stages:\n" + "\n".join(stages) + "\n")
    subprocess.run([BIN / "dvc", "init", "--no-scm", "-q"], cwd=tmp_path, check=True, env=_env())
    return tmp_path


def _env() -> dict[str, str]:
    return {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}


def _plan(project: Path, *flags: str, keep_going: bool = False) -> ReproducePlan:
    command = (str(BIN / "dvc"), "repro", *flags)
    return ReproducePlan(project, (), command, _env(), False, jobs=2, keep_going=keep_going)


def _interval(project: Path, name: str) -> tuple[float, float]:
    times = dict(line.split() for line in (project / "log" / name).read_text().splitlines())
    return float(times["start"]), float(times["end"])


def _overlap(one: tuple[float, float], other: tuple[float, float]) -> bool:
    return one[0] < other[1] and other[0] < one[1]


def test_waits_for_pending_stages_through_stages_that_need_not_run():
    edges = [("a", "b"), ("b", "c"), ("x", "c")]
    plan = plan_stages({"a", "c", "x"}, edges, ["a", "b", "x", "c"], frozenset({"x"}))
    assert plan.waits_for["c"] == {"a", "x"}  # through b, which is up to date
    assert plan.order.index("c") > max(plan.order.index("a"), plan.order.index("x"))
    assert plan.alone == {"x"}


def test_independent_stages_overlap_and_the_result_is_what_dvc_repro_leaves(tmp_path):
    project = _project(tmp_path)
    out = io.StringIO()
    assert _run_side_by_side(_plan(project), out) == 0, out.getvalue()
    a, b, c, d, e = (_interval(project, n) for n in "abcde")
    assert _overlap(a, b), (a, b)
    assert c[0] >= max(a[1], b[1]) and e[0] >= c[1]
    assert not any(_overlap(d, other) for other in (a, b, c, e))
    status = subprocess.run(
        [BIN / "dvc", "status"], cwd=project, env=_env(), capture_output=True, text=True
    )
    assert "up to date" in status.stdout, status.stdout
    assert "5 stage(s) ran" in out.getvalue() and "s wall" in out.getvalue()
    # nothing is pending afterwards; a second run starts no stage
    pending, _, _ = pending_stages(_plan(project))
    assert pending == set()


@pytest.mark.parametrize("keep_going", [False, True])
def test_a_failed_stage_stops_what_depends_on_it(tmp_path, keep_going):
    project = _project(tmp_path, fail="a")
    out = io.StringIO()
    code = _run_side_by_side(_plan(project, keep_going=keep_going), out)
    assert code != 0
    text = out.getvalue()
    assert "stage FAILED: a" in text
    assert not (project / "out" / "c").exists() and not (project / "out" / "e").exists()
    assert (project / "out" / "b").exists()  # started beside a before a failed
    if keep_going:  # d depends on nothing that failed
        assert (project / "out" / "d").exists()
    assert "started: c" not in text and "started: e" not in text


@pytest.mark.parametrize("jobs", [0, -1, True])
def test_jobs_must_be_a_positive_whole_number(tmp_path, jobs):
    from rigmap.app.params import ParamsError
    from rigmap.reproduce import plan_reproduce

    with pytest.raises(ParamsError, match="--jobs"):
        plan_reproduce([], project=tmp_path, jobs=jobs)


def test_a_stage_marked_starts_early_takes_the_first_free_slot(tmp_path):
    """``long`` waits for ``a`` only; when ``a`` ends, ``long`` takes the free slot before
    the ready stages ahead of it in DVC's order (b, c1-c3 need nothing)."""
    (tmp_path / "log").mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / ".gitignore").write_text("")
    rows = [("a", [], 0.3, False), ("b", [], 1.5, False)]
    rows += [(f"c{i}", [], 0.4, False) for i in (1, 2, 3)] + [("long", ["a"], 0.5, True)]
    lines = ["stages:"]
    for name, deps, sleep, early in rows:
        lines += [f"  {name}:", f"    cmd: {STAGE.format(name=name, sleep=sleep)}"]
        lines += ["    meta: {starts_early: true}"] if early else []
        lines += [f"    deps: [{', '.join('out/' + d for d in deps)}]"] if deps else []
        lines += [f"    outs: [out/{name}]"]
    (tmp_path / "dvc.yaml").write_text("\n".join(lines) + "\n")
    subprocess.run([BIN / "dvc", "init", "--no-scm", "-q"], cwd=tmp_path, check=True, env=_env())
    out = io.StringIO()
    assert _run_side_by_side(_plan(tmp_path), out) == 0, out.getvalue()
    lines = out.getvalue().splitlines()
    after_a = lines[next(i for i, line in enumerate(lines) if "stage done: a " in line) :]
    started = [line.split("started: ")[1].split(",")[0] for line in after_a if "started: " in line]
    assert started[0] == "long" and len(started) > 1, lines  # before the stages still waiting
    assert _interval(tmp_path, "long")[0] >= _interval(tmp_path, "a")[1]


def test_the_stages_a_starts_early_stage_waits_for_are_offered_first_too():
    """``poses_b`` feeds the early ``long_b``: it is offered a slot before ``other``, which
    comes first in DVC's order, so the long chain is not held up by short stages."""
    from rigmap.stage_jobs import plan_stages

    nodes = ["corpus_a", "corpus_b", "other", "long_a", "poses_b", "long_b", "after"]
    edges = [("corpus_a", "long_a"), ("corpus_b", "poses_b"), ("poses_b", "long_b")]
    edges += [("long_a", "after"), ("other", "after")]
    plan = plan_stages(set(nodes), edges, nodes, early_families=frozenset({"long_a", "long_b"}))
    assert plan.early == {"corpus_a", "corpus_b", "poses_b", "long_a", "long_b"}
    offered = plan.start_order()
    assert offered.index("poses_b") < offered.index("other") < offered.index("after")
    assert offered[:5] == ["corpus_a", "corpus_b", "long_a", "poses_b", "long_b"]
