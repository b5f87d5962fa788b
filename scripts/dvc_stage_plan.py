"""Every stage of a project's dvc.yaml as DVC resolves it, as JSON: to diff two versions.

    python scripts/dvc_stage_plan.py [PROJECT] [-o PLAN.json]
    python scripts/dvc_stage_plan.py --compare BEFORE.json AFTER.json

A rewrite of dvc.yaml (anchors, ``vars:``, flow style, comments moved out) must leave what
DVC plans unchanged. The plan is read through DVC's own API (``Repo.index.stages``), so
matrices, interpolation and YAML merges are expanded as ``dvc repro`` expands them: per
stage its command, sorted dependencies, params, outputs with their cache/metric/plot/
persist flags, meta, frozen and always_changed. Dependency and output order is left out
(dvc.lock sorts them by path). ``families`` is what rigmap's own code reads from the raw
YAML (``rigmap.app.placeholders`` the matrix lists, ``rigmap.stage_jobs`` the meta) and
``interpolated`` the params.yaml keys it finds named in the text (``rigmap.app.params``).
``--compare`` prints what differs and exits 1 when anything does; ``--check-lock`` does the
same between the stages and the definitions the dvc.lock files were written for (paths and
commands), and names lock entries no stage has any more (DVC keeps them; each one slows
every rewrite of its file).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _out(out) -> dict:
    """An output's path and the flags DVC keeps for it (the plot's x/y among them)."""
    entry = {"path": out.def_path, "cache": out.use_cache, "metric": bool(out.metric)}
    entry["plot"] = out.plot if isinstance(out.plot, dict) else bool(out.plot)
    entry["persist"] = out.persist
    return entry


def _stage(stage) -> dict:
    from dvc.dependency import ParamsDependency

    params = {
        dep.def_path: sorted(map(str, dep.params))
        for dep in stage.deps
        if isinstance(dep, ParamsDependency)
    }
    deps = sorted(d.def_path for d in stage.deps if not isinstance(d, ParamsDependency))
    return {
        "cmd": stage.cmd,
        "deps": deps,
        "params": params,
        "outs": sorted((_out(o) for o in stage.outs), key=lambda o: o["path"]),
        "meta": stage.meta,
        "frozen": stage.frozen,
        "always_changed": stage.always_changed,
        "wdir": Path(stage.wdir).relative_to(Path(stage.repo.root_dir)).as_posix(),
    }


def plan(project: Path) -> dict:
    """``{"stages": {name: resolved stage}, "families": {...}, "interpolated": [...]}``."""
    from dvc.repo import Repo

    with Repo(str(project)) as repo:
        stages = {stage.name: _stage(stage) for stage in repo.index.stages}
    from rigmap.app.params import interpolated_params
    from rigmap.store.pipeline_files import stage_families

    families = {
        name: {"matrix": found.body.get("matrix"), "meta": found.body.get("meta")}
        for name, found in stage_families(project).items()
    }

    return {
        "stages": dict(sorted(stages.items())),
        "families": dict(sorted(families.items())),
        "interpolated": sorted(interpolated_params(project / "dvc.yaml")),
    }


def lock_mismatches(project: Path, stages: dict) -> list[str]:
    """Where dvc.lock was written for other stage definitions: command, dependency, output
    or params paths (what ``dvc status`` compares besides hashes and values)."""
    lock = lock_entries(project)
    found = [f"{name}: not in dvc.lock" for name in sorted(set(stages) - set(lock))]
    found += [f"{name}: in dvc.lock, not a stage" for name in sorted(set(lock) - set(stages))]
    for name in sorted(set(stages) & set(lock)):
        stage, entry = stages[name], lock[name]
        written = {
            "cmd": entry.get("cmd"),
            "deps": sorted(d["path"] for d in entry.get("deps", [])),
            "outs": sorted(o["path"] for o in entry.get("outs", [])),
            "params": {f: sorted(v) for f, v in entry.get("params", {}).items()},
        }
        planned = {
            "cmd": stage["cmd"],
            "deps": stage["deps"],
            "outs": [o["path"] for o in stage["outs"]],
            "params": _lock_params(project, stage["params"]),
        }
        found += differences(written, planned, name)
    return found


def lock_entries(project: Path) -> dict:
    """Every stage file's dvc.lock entries, by stage name (a file not run yet has none)."""
    import yaml

    from rigmap.store.pipeline_files import pipeline_files

    entries = {}
    for path in pipeline_files(project):
        lock = project / path.parent / "dvc.lock"
        if lock.is_file():
            entries.update(yaml.safe_load(lock.read_text(encoding="utf-8"))["stages"])
    return entries


def _lock_params(project: Path, params: dict) -> dict:
    """A stage's params as dvc.lock names them: a whole file tracked lists all its keys."""
    import yaml

    named = {}
    for path, keys in params.items():
        if not keys:  # {params.yaml: null}: every top-level key
            keys = sorted(yaml.safe_load((project / path).read_text(encoding="utf-8")))
        named[path] = sorted(keys)
    return named


def differences(before: dict, after: dict, where: str = "") -> list[str]:
    """Every path at which two JSON trees differ, with both values."""
    if isinstance(before, dict) and isinstance(after, dict):
        found = []
        for key in sorted(set(before) | set(after)):
            if key not in after:
                found.append(f"{where}/{key}: only before")
            elif key not in before:
                found.append(f"{where}/{key}: only after")
            else:
                found += differences(before[key], after[key], f"{where}/{key}")
        return found
    if before == after:
        return []
    if isinstance(before, list) and isinstance(after, list) and not _has_dicts(before + after):
        gone = [item for item in before if item not in after]
        new = [item for item in after if item not in before]
        if gone or new:  # not only reordered
            return [f"{where}: removed {gone!r}, added {new!r}"]
    return [f"{where}: {before!r} -> {after!r}"]


def _has_dicts(items: list) -> bool:
    return any(isinstance(item, dict | list) for item in items)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("project", nargs="?", default=".", help="folder with dvc.yaml")
    parser.add_argument("-o", "--output", help="write the plan here (default: stdout)")
    parser.add_argument("--compare", nargs=2, metavar=("BEFORE", "AFTER"))
    parser.add_argument(
        "--check-lock", action="store_true", help="compare the stages with dvc.lock's entries"
    )
    args = parser.parse_args(argv)
    if args.compare:
        before, after = (json.loads(Path(p).read_text()) for p in args.compare)
        found = differences(before, after)
        print(json.dumps({"stages": len(after.get("stages", {})), "differences": found}, indent=1))
        return 1 if found else 0
    project = Path(args.project)
    if not (project / "dvc.yaml").is_file():
        parser.error(f"project: no dvc.yaml in {project}")
    planned = plan(project)
    if args.check_lock:
        found = lock_mismatches(project, planned["stages"])
        print(json.dumps({"stages": len(planned["stages"]), "differences": found}, indent=1))
        return 1 if found else 0
    text = json.dumps(planned, indent=1, sort_keys=True) + "\n"
    if args.output:
        Path(args.output).write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
