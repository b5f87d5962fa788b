"""Compare the errors of two metrics trees (``metrics/`` of two runs), ignoring timings.

    python scripts/compare_metrics.py OLD_METRICS NEW_METRICS [--tolerance 1e-9]

Walks every ``*.json`` under both folders, pairs files by relative path and compares the
error numbers (``joint_error``, ``ground_truth_error`` and every other number whose key
is not a timing: ``total_time_s``, ``fps`` and keys ending in ``_s`` are skipped) per
average and per clip. Prints JSON: files compared, files only on one side, and every
number whose relative difference exceeds the tolerance, largest first. Exit status 1
when anything differs, so CI and people can use it as a check.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

TIMING_KEYS = {"total_time_s", "fps", "seconds", "wall_time_s"}


def numbers(value, prefix=""):
    """Every non-timing number in a JSON document, keyed by its path."""
    if isinstance(value, dict):
        for key, item in value.items():
            if key in TIMING_KEYS or key.endswith("_s") or key == "units":
                continue
            yield from numbers(item, f"{prefix}/{key}")
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from numbers(item, f"{prefix}[{index}]")
    elif isinstance(value, int | float) and not isinstance(value, bool):
        yield prefix, float(value)


def relative_difference(a: float, b: float) -> float:
    if math.isnan(a) and math.isnan(b):
        return 0.0
    scale = max(abs(a), abs(b), 1e-300)
    return abs(a - b) / scale


def compare(old_root: Path, new_root: Path, tolerance: float) -> dict:
    old_files = {p.relative_to(old_root) for p in old_root.rglob("*.json")}
    new_files = {p.relative_to(new_root) for p in new_root.rglob("*.json")}
    differences = []
    for name in sorted(old_files & new_files):
        old = dict(numbers(json.loads((old_root / name).read_text())))
        new = dict(numbers(json.loads((new_root / name).read_text())))
        for key in sorted(old.keys() | new.keys()):
            if key not in old or key not in new:
                differences.append(
                    {
                        "file": str(name),
                        "key": key,
                        "old": old.get(key),
                        "new": new.get(key),
                        "relative": None,
                    }
                )
                continue
            rel = relative_difference(old[key], new[key])
            if rel > tolerance:
                differences.append({"file": str(name), "key": key, "old": old[key],
                                    "new": new[key], "relative": rel})  # fmt: skip
    differences.sort(key=lambda d: -(d["relative"] if d["relative"] is not None else math.inf))
    return {
        "tolerance": tolerance,
        "files_compared": len(old_files & new_files),
        "only_old": sorted(map(str, old_files - new_files)),
        "only_new": sorted(map(str, new_files - old_files)),
        "numbers_differing": len(differences),
        "differences": differences,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--tolerance", type=float, default=1e-9, help="relative (default 1e-9)")
    parser.add_argument("--only", default="", help="compare only files whose path contains this")
    args = parser.parse_args(argv)
    for root in (args.old, args.new):
        if not root.is_dir():
            parser.error(f"{root} is not a folder")
    result = compare(args.old, args.new, args.tolerance)
    if args.only:
        result["differences"] = [d for d in result["differences"] if args.only in d["file"]]
        result["numbers_differing"] = len(result["differences"])
    json.dump(result, sys.stdout, indent=2)
    print()
    clean = not (result["numbers_differing"] or result["only_old"] or result["only_new"])
    return 0 if clean else 1


if __name__ == "__main__":
    sys.exit(main())
