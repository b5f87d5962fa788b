"""Do two metrics trees agree on Table 1's network rows within their spread over seeds?

    python scripts/seed_spread.py METRICS_A METRICS_B

For every network row (rig × method of ``rigmap.reports.seed_spread.NETWORK_METHODS``, found
in ``<rig>/methods/``) and both errors of its Average (``joint_error``,
``ground_truth_error``), the median and the spread (max - min) over seed 0
(``methods/``) and the replicate seeds (``methods_seed<k>/``) of each tree; the row agrees
when ``|median_A - median_B| <= max(spread_A, spread_B)``. Prints JSON; exit status 1 when
any row disagrees or is in one tree only (2 on unreadable input).

The trees are typically two clean clones' quick replications, the second on another host
or on another CPU code path forced by environment, set before the run:

    ATEN_CPU_CAPABILITY=default dvc repro ...   # torch's own kernels without AVX2/AVX-512

Measured on this project's AVX-512 host with torch 2.13's CPU wheel
(``benchmarks/cpu_code_path.py``, ``benchmarks/results/cpu_code_path_s36.json``): 300 Adam
steps of the NN rows' network end 4.2e-7 apart in their predictions with
``ATEN_CPU_CAPABILITY=default``, and bit-identical with ``ATEN_CPU_CAPABILITY=avx2``,
``ONEDNN_MAX_CPU_ISA=SSE41``, ``MKL_ENABLE_INSTRUCTIONS=SSE4_2`` or ``OPENBLAS_CORETYPE``
alone (those libraries do not run these small float32 products here), so the first is
the setting that stands in for another machine.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rigmap.reports.metrics_tree import ReportInputError, read_result
from rigmap.reports.seed_spread import MEASURES, NETWORK_METHODS, Spread, read_replicates

USAGE = "usage: python scripts/seed_spread.py METRICS_A METRICS_B"


def spreads(root: Path) -> dict[str, Spread]:
    """``<rig>/<method>/<measure>`` -> its spread over seeds, for every network row."""
    if not root.is_dir():
        raise ReportInputError(f"{root}: not a metrics folder")
    found = {}
    for methods in sorted(root.glob("*/methods")):
        rig = methods.parent.name
        replicates = read_replicates(methods.parent, rig)
        for path in sorted(methods.glob("*.json")):
            method, _, sampler = path.stem.partition("-")
            if method not in NETWORK_METHODS:
                continue
            results = [read_result(path, rig=rig, method=method, sampler=sampler)]
            results += [seed[method] for seed in replicates.values() if method in seed]
            for measure in MEASURES:
                values = [getattr(r.average, measure) for r in results]
                found[f"{rig}/{method}/{measure}"] = Spread.of(values)
    return found


def compare_trees(a: dict[str, Spread], b: dict[str, Spread]) -> dict:
    """Each row's medians, spreads and agreement; rows in one tree only are listed apart."""
    rows = []
    for key in sorted(set(a) & set(b)):
        gap = abs(a[key].median - b[key].median)
        allowed = max(a[key].width, b[key].width)
        rows.append(
            {
                "row": key,
                "median_a": a[key].median,
                "median_b": b[key].median,
                "spread_a": a[key].width,
                "spread_b": b[key].width,
                "seeds_a": a[key].seeds,
                "seeds_b": b[key].seeds,
                "difference": gap,
                "agree": gap <= allowed,
            }
        )
    only = {"only_a": sorted(set(a) - set(b)), "only_b": sorted(set(b) - set(a))}
    disagree = [row["row"] for row in rows if not row["agree"]]
    agree = not disagree and not only["only_a"] and not only["only_b"]
    return {"rows": rows, **only, "disagree": disagree, "agree": agree}


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(USAGE, file=sys.stderr)
        return 2
    try:
        result = compare_trees(spreads(Path(argv[0])), spreads(Path(argv[1])))
    except ReportInputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(json.dumps(result, indent=2))
    return 0 if result["agree"] else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
