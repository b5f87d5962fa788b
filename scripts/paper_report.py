"""reports/paper/ from scripts/paper_table1.sh's run: Table 1, figures, stage times, ratios.

Table 1 and the figures are the report's own (:func:`rigmap.reports.build_report` on the
paper run's metrics, Table 1's rigs only); beside them ``stage_times.md`` (each stage's
wall time and the load after it), ``scale_free.md`` (each method's joint error divided by
the same table's GPR row, and its joint RMS as % of the character's height, for the quick
run's committed metrics, the paper run and the published Table 1: the paper never states
its unit, so only ratios compare across the three) and the paper run's metrics files.

    python scripts/paper_report.py --out paper-run --reports reports/paper --rigs quadruped biped
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path

from rigmap.reports import ReportSettings, build_report, published

ROOT = Path(__file__).resolve().parents[1]
#: Table 1's rows in the paper's order, then ours
METHODS = (
    ("script", "none"),
    ("gpr", "none"),
    ("gpr_learned_jacobian", "none"),
    ("gpr_computed_jacobian", "none"),
    ("nn", "pca_gaussian"),
    ("nn_computed_jacobian", "pca_gaussian"),
    ("nn_learned_jacobian", "pca_gaussian"),
    ("nn_joint_space", "none"),
    ("nn_joint_space_computed_jacobian", "none"),
    ("nn_joint_space_tuned", "none"),
    ("mean", "none"),
)
TABLE1_FIGURES = ("time_per_method.png", "confidence.png")


def averages(metrics: Path, rig: str) -> dict[str, dict]:
    """``method -> average`` of a run's Table 1 metrics files for ``rig`` (present ones)."""
    found = {}
    for method, sampler in METHODS:
        path = metrics / rig / "methods" / f"{method}-{sampler}.json"
        if path.is_file():
            found[method] = json.loads(path.read_text())["average"]
    return found


def published_ratios(rig: str) -> dict[str, float]:
    """The published Table 1 average joint error of each method ÷ its GPR row's."""
    rows = {
        row.method: published.as_number(row.joint_error)
        for row in published.TABLE1
        if row.character == rig and row.motion == published.AVERAGE
    }
    return {method: value / rows["gpr"] for method, value in rows.items()} if rows else {}


def scale_free_table(rigs: list[str], out: Path) -> str:
    lines = [
        "## Table 1 in scale-free units: quick run, paper budget, published",
        "",
        "Joint error ÷ the same table's GPR row (the paper never states its unit, so only "
        "ratios compare with it), and ours as joint RMS in % of the character's rest height.",
        "",
        "| rig | method | quick ÷ GPR | paper ÷ GPR | published ÷ GPR | quick RMS % "
        "| paper RMS % |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for rig in rigs:
        quick, paper = averages(ROOT / "metrics", rig), averages(out / "metrics", rig)
        printed = published_ratios(rig)
        for method, _ in METHODS:
            if method not in quick and method not in paper:
                continue
            cells = [rig, method]
            for run in (quick, paper):
                cells.append(f"{run[method]['joint_error'] / run['gpr']['joint_error']:.3g}"
                             if method in run and "gpr" in run else "—")  # fmt: skip
            cells.append(f"{printed[method]:.3g}" if method in printed else "—")
            for run in (quick, paper):
                value = run.get(method, {}).get("joint_rms_percent_of_height")
                cells.append(f"{value:.3g}" if value is not None else "—")
            lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def stage_times(rigs: list[str], out: Path) -> str:
    lines = ["## Wall time of each stage (experiment=paper, scripts/paper_table1.sh)", ""]
    lines += ["| rig | stage | seconds | 1-min load after |", "| --- | --- | ---: | ---: |"]
    for rig in rigs:
        for line in (out / f"{rig}.times").read_text().splitlines():
            name, seconds, *rest = line.split(maxsplit=2)
            load = rest[0].removeprefix("load_after=") if rest else ""
            lines.append(f"| {rig} | {name} | {float(seconds):.1f} | {load} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("paper-run"))
    parser.add_argument("--reports", type=Path, default=Path("reports/paper"))
    parser.add_argument("--rigs", nargs="+", default=["quadruped", "biped"])
    args = parser.parse_args()
    missing = [str(args.out / f"{rig}.times") for rig in args.rigs
               if not (args.out / f"{rig}.times").is_file()]  # fmt: skip
    if missing:
        raise SystemExit(f"paper_report: no stage times {missing}: run scripts/paper_table1.sh")
    settings = ReportSettings.from_mapping(
        {"rigs": args.rigs, "method_rigs": args.rigs, "sampler_rigs": [], "blend_file_rigs": []}
    )
    with tempfile.TemporaryDirectory() as scratch:
        files = build_report(
            metrics_root=args.out / "metrics",
            data_root=args.out / "data",
            reports_root=scratch,
            settings=settings,
        )
        staging = Path(scratch) / "paper"
        (staging / "figures").mkdir(parents=True)
        for path in files.tables["table1_methods"].values():
            shutil.copy2(path, staging / path.name)
        for figure in files.figures:
            name = figure.path.name
            if name in TABLE1_FIGURES or name.startswith("per_frame_"):
                shutil.copy2(figure.path, staging / "figures" / name)
        for rig in args.rigs:
            shutil.copytree(args.out / "metrics" / rig / "methods", staging / "metrics" / rig)
        (staging / "stage_times.md").write_text(stage_times(args.rigs, args.out))
        (staging / "scale_free.md").write_text(scale_free_table(args.rigs, args.out))
        if args.reports.exists():
            shutil.rmtree(args.reports)
        args.reports.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(staging, args.reports)
    print(f"paper report: {args.reports}")


if __name__ == "__main__":
    main()
