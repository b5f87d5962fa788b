"""Print the README's Table 1 (averages over the test clips) from the report's CSV.

    python scripts/readme_table1.py reports/tables/table1_methods.csv

The README quotes the committed run; this keeps its table a copy of
``reports/tables/table1_methods.csv`` instead of numbers typed by hand. Network rows
(trained with replicate seeds, issue #36) show the median joint and ground-truth error over
the seeds with the joint error's least–greatest in brackets; the other columns are seed 0's.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

GROUPS = (
    ("Script", ("script",)),
    ("GPR / NN", ("gpr", "nn")),
    ("GPR / NN & Learned Jacobian", ("gpr_learned_jacobian", "nn_learned_jacobian")),
    ("GPR / NN & Computed Jacobian", ("gpr_computed_jacobian", "nn_computed_jacobian")),
    (
        "Joint-space NN / & CJ / tuned on the clip",
        ("nn_joint_space", "nn_joint_space_computed_jacobian", "nn_joint_space_tuned"),
    ),
    ("Mean predictor", ("mean",)),
)
RIG_LABELS = {
    "quadruped": "quadruped",
    "biped": "biped",
    "face": "face (mesh rig, its 6 landmarks)",
    "squirrel": "squirrel (mesh rig, its 1 125 vertices)",
    "rigify_wolf": "rigify_wolf (Blender, first 12 frames per clip)",
    "blend_file:hero": "blend_file:hero (rigmap's .blend fixture, 12 frames of its test clip)",
}
HEADER = (
    "| rig | method | joint error (median [min–max] over seeds for networks) | % of height "
    "| ÷ mean | ground-truth error | frames/s |\n|---|---|---|---|---|---|---|"
)


def number(value: float, kind: str = "") -> str:
    """Two or three significant digits, thousands spaced, as a reader scans a table."""
    x = float(value)
    if kind == "fps" and x >= 10_000:
        return f"{round(x, -3):,.0f}".replace(",", " ")
    if x == 0:
        return "0"
    if abs(x) >= 1000:
        return f"{x:,.0f}".replace(",", " ")
    if abs(x) >= 20:
        return f"{x:.0f}"
    if kind == "rel":
        return f"{x:.3f}" if abs(x) < 0.01 else f"{x:.2f}"
    return f"{x:.2g}" if abs(x) < 1 and kind != "fps" else f"{x:.3g}"


def joint_error(row: dict[str, str]) -> str:
    """The median with its least–greatest when the row was trained over several seeds."""
    seeds = row.get("seeds") or ""
    if seeds and int(float(seeds)) > 1 and row.get("joint_error_median"):
        low, high = number(row["joint_error_min"]), number(row["joint_error_max"])
        return f"{number(row['joint_error_median'])} [{low}–{high}]"
    return number(row["joint_error"])


def ground_truth(row: dict[str, str]) -> str:
    median = row.get("ground_truth_error_median")
    return number(median if median else row["ground_truth_error"])


def table(path: Path) -> str:
    with open(path, newline="") as handle:
        rows = {
            (r["rig"], r["method"]): r for r in csv.DictReader(handle) if r["motion"] == "Average"
        }
    lines = [HEADER]
    for rig, label in RIG_LABELS.items():
        first = True
        for name, methods in GROUPS:
            if not all((rig, m) in rows for m in methods):
                continue
            picked = [rows[(rig, m)] for m in methods]
            cells = [
                " / ".join(joint_error(r) for r in picked),
                " / ".join(number(r["joint_rms_percent_of_height"]) for r in picked),
                " / ".join(number(r["joint_error_relative_to_mean"], "rel") for r in picked),
                " / ".join(ground_truth(r) for r in picked),
                " / ".join(number(r["fps"], "fps") for r in picked),
            ]
            shown = "Script (constraints)" if rig == "rigify_wolf" and name == "Script" else name
            lines.append(f"| {label if first else ''} | {shown} | " + " | ".join(cells) + " |")
            first = False
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not Path(argv[0]).is_file():
        print("usage: readme_table1.py reports/tables/table1_methods.csv", file=sys.stderr)
        return 2
    print(table(Path(argv[0])))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
