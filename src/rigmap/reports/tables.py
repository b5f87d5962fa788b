"""The paper's comparison tables built from our metrics, with its published values beside them.

- ``methods_table``  — Table 1: per test clip and Average, every method;
- ``sampling_table`` — Table 2: the network trained on each supersampler;
- ``rigs_table``     — Table 3: training frames, rig DOFs and joint DOFs;
- ``kernels_table``  — §7.1: GPR with each kernel (the paper gives no numbers);
- ``splits_table``   — Table 1's regression rows on the training frames, on new takes of the
  training motions (in distribution) and on the test clips (extreme), side by side (ours).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from rigmap.reports import published
from rigmap.reports.catalog import rig_label
from rigmap.reports.metrics_tree import LoadedResult, Numbers, ReportInputError, RigMetrics
from rigmap.reports.rig_facts import RigFacts
from rigmap.reports.seed_spread import Spread, compare, row_spread
from rigmap.reports.settings import ReportSettings
from rigmap.reports.table import MISSING, Column, Table, format_error, format_seconds

OURS = "rigmap (this run)"
SQUARE = "\u00b2"

JOINT_ERROR_NOTE = (
    "Joint Error: mean squared difference between the joint positions the method's controls "
    "produce and the targets, over frames and the 3J joint coordinates, in the rig's length "
    "unit squared (×3 for the mean squared joint distance)."
)
GROUND_TRUTH_NOTE = (
    "Ground Truth Error: mean squared difference to the animator's controls, each control "
    "divided by its standard deviation in the training corpus (rotations in radians); "
    "dimensionless."
)
SCALE_FREE_NOTE = (
    "Joint RMS: the root mean squared joint distance, √(3 × Joint Error), in the rig's length "
    "unit and as % of the character's rest height (the vertical extent of its joints at the "
    "default controls), so rigs of any size compare. 'Joint Error ÷ Mean Predictor's' divides "
    "by the error, on the same frames, of the mean predictor (the training corpus's mean "
    "controls on every frame, placed like every regressor; the Mean Predictor row): 1 recovers "
    "nothing of the pose, 0 all of it. The paper never states its unit, so its columns are "
    "compared in shape, not in value."
)
TIME_NOTE = (
    "Total Time: wall-clock seconds for the clip (warm-up frames excluded); Frames per Sec = "
    "frames / Total Time; measured on the machine that ran the evaluate stage."
)
PUBLISHED_NOTE = (
    f"Columns labelled '{published.LABEL}' are the values printed in {published.SOURCE}; they "
    "were measured on the authors' Maya characters with their own animation and units, so "
    "they orient, they are not a target."
)


def _unit_label(units: set[str]) -> str:
    return f"{units.pop()}{SQUARE}" if len(units) == 1 else f"length unit{SQUARE}"


# --------------------------------------------------------------------------- Table 1
def methods_table(tree: Mapping[str, RigMetrics], settings: ReportSettings) -> Table:
    """Table 1: rows Character/Motion × Method, per clip and Average, ours then published."""
    others = {
        rig_label(rig): _tables_holding(rig, metrics, settings)
        for rig, metrics in tree.items()
        if not settings.methods_for(rig)
    }
    tree = {rig: metrics for rig, metrics in tree.items() if settings.methods_for(rig)}
    unit = _unit_label({r.length_unit for m in tree.values() for r in m.methods.values()})
    columns = _methods_columns(unit)

    rows, classes, records, budget_notes = [], [], [], []
    for rig, metrics in tree.items():
        methods = settings.methods_for(rig)
        first = frames_per_clip(metrics, methods)
        if first is not None:
            budget_notes.append(_frame_budget_note(metrics, methods, first))
        for motion in (*metrics.test_clips, published.AVERAGE):
            shown = motion if first is None else f"{motion} (first {first} frames)"
            for index, method in enumerate(methods):
                result = metrics.methods[method]
                numbers = _motion_numbers(result, motion)
                baseline = _mean_predictor(metrics, motion)
                row_kind = settings.catalogue.method(method)
                paper = published.table1_value(rig, motion, method)
                label = f"{rig_label(rig)} — {shown}" if index == 0 else ""
                spreads = _row_spreads(metrics, result, motion)
                cells = [label, row_kind.display, *_method_cells(numbers, baseline, spreads)]
                rows.append(cells + _paper_cells(paper))
                css = ["group-start" if index == 0 else ""]
                css += ["average" if motion == published.AVERAGE else "", "extra" * row_kind.extra]
                classes.append(" ".join(c for c in css if c))
                records.append(
                    {
                        "rig": rig,
                        "motion": motion,
                        "method": method,
                        "method_label": row_kind.label,
                        "extra": row_kind.extra,
                        "sampler": result.sampler,
                        **_number_record(numbers),
                        **_spread_record(numbers, spreads),
                        **_relative_record(numbers, baseline),
                        "novelty_error_spearman": result.novelty_spearman
                        if motion == published.AVERAGE
                        else None,
                        "length_unit": result.length_unit,
                        "frames_per_clip": first,
                        **_paper_record(paper),
                    }
                )
    notes = _methods_notes(settings) + budget_notes + run_budget_notes(tree, settings)
    notes += _left_out_notes(tree, others, settings)
    notes += seed_notes(tree, settings)
    return Table(
        name="table1_methods",
        title="Table 1 — inverse rig mapping methods on the test clips",
        columns=columns,
        rows=rows,
        data=pd.DataFrame.from_records(records),
        notes=notes,
        row_classes=classes,
    )


def _methods_columns(unit: str) -> list[Column]:
    """Table 1's columns: ours (a network row's errors with their min–max over seeds), then
    the published values."""
    distance = unit.removesuffix(SQUARE)
    value_labels = [
        f"Joint Error ({unit})",
        f"Joint RMS ({distance})",
        "Joint RMS (% of height)",
        "Joint Error ÷ Mean Predictor's",
        "Ground Truth Error",
        "Total Time (s)",
        "Frames per Sec",
    ]
    columns = [Column("Character/Motion", numeric=False), Column("Method", numeric=False)]
    columns += [Column(label, OURS, short_group="") for label in value_labels]
    columns.insert(3, Column("Joint Error min–max (seeds)", OURS, numeric=False, short_group=""))
    columns.insert(8, Column("Ground Truth min–max (seeds)", OURS, numeric=False, short_group=""))
    columns += [
        Column(label, published.LABEL, short_group="published")
        for label in (
            "Joint Error (unit not stated)",
            "Ground Truth Error",
            "Total Time (s)",
            "Frames per Sec",
        )
    ]
    return columns


def _methods_notes(settings: ReportSettings) -> list[str]:
    """Table 1's first notes: the measures, the models behind the rows, the extra rows."""
    extras = [m.label for m in settings.catalogue.methods if m.extra and m.key in settings.methods]
    notes = [
        JOINT_ERROR_NOTE,
        SCALE_FREE_NOTE,
        GROUND_TRUTH_NOTE,
        TIME_NOTE,
        f"GPR rows use the GPR fitted on the train corpus (multiquadric kernel unless the "
        f"experiment says otherwise); NN rows use the network trained on the corpus plus "
        f"'{settings.catalogue.sampler(settings.nn_sampler).label}' supersamples.",
        PUBLISHED_NOTE + " The paper's 'Maya Script' is our Script row.",
    ]
    if extras:
        notes.append(f"Rows marked (extra) are not in the paper: {', '.join(extras)}.")
    return notes


def _tables_holding(rig: str, metrics: RigMetrics, settings: ReportSettings) -> str:
    """Where a rig without Table 1 rows does appear, from what the metrics hold."""
    per_rig = rig in settings.sampler_rigs
    tables = ["Table 2"] if per_rig and metrics.samplers else []
    tables.append("Table 3")
    if per_rig and metrics.kernels:
        tables.append("the kernel table")
    return tables[0] if len(tables) == 1 else ", ".join(tables[:-1]) + " and " + tables[-1]


def _left_out_notes(tree, others: Mapping[str, str], settings: ReportSettings) -> list[str]:
    """Table 1's last notes: the rigs compared elsewhere (and where), and methods an
    experiment skips."""
    notes = []
    if others:
        compared = ", ".join(rig_label(rig) for rig in tree)
        where = "; ".join(f"{label} appears in {tables}" for label, tables in others.items())
        notes.append(f"Like the paper, the methods are compared on {compared}; {where}.")
    excluded = {
        r: ms for r, ms in settings.excluded_methods.items() if r in settings.method_rigs and ms
    }
    for rig, left_out in excluded.items():
        labels = ", ".join(settings.catalogue.method(m).label for m in left_out)
        notes.append(f"{rig_label(rig)}: not evaluated by this experiment: {labels}.")
    return notes


def frames_per_clip(metrics: RigMetrics, methods: Sequence[str]) -> int | None:
    """The per-clip frame budget the rig's Table 1 runs were scored with (None: whole clips).

    Read from the metrics files (``extra.frames_per_clip``, written by the evaluate
    stage); the methods of one rig must agree, or their rows would not compare.
    """
    budgets = {metrics.methods[m].extra.get("frames_per_clip") for m in methods}
    if len(budgets) > 1:
        files = ", ".join(metrics.methods[m].path.name for m in methods)
        raise ReportInputError(
            f"rig {metrics.rig!r}: the Table 1 metrics files were scored on different frames "
            f"per clip ({sorted(budgets, key=str)}); re-run its evaluate stage ({files})"
        )
    budget = budgets.pop() if budgets else None
    return None if budget is None else int(budget)


def _frame_budget_note(metrics: RigMetrics, methods: Sequence[str], first: int) -> str:
    """Why a rig's rows cover only the first frames of its clips, and its GPR's size."""
    note = (
        f"{rig_label(metrics.rig)}: every method is scored on the first {first} frames of each "
        f"test clip (evaluate.frames_per_clip={first}), the experiment's budget for this rig: "
        "computed-Jacobian refinement evaluates the rig about 2 × (used controls) times per "
        "frame and iteration (central differences), and a slow rig (a DCC's) pays for each; "
        "the Average is over those frames."
    )
    points = {
        metrics.methods[m].extra.get("budget", {}).get("gpr_points")
        for m in methods
        if m.startswith("gpr")
    } - {None}
    if len(points) == 1:
        note += f" Its GPR keeps {points.pop()} support points (budget.gpr_points)."
    return note


#: how a run budget's values read in the report (budget.* of the metrics files' ``extra``)
BUDGET_PHRASES = (
    ("gpr_points", "GPR of {} support points"),
    ("length_scales", "{} length scales"),
    ("cv_splits", "{} cross-validation splits"),
    ("hidden", "network of {} hidden units"),
    ("epochs", "{} epochs"),
    ("samples", "{} supersamples"),
    ("refine_iterations", "refinement of at most {} iterations"),
)


def run_budget_notes(tree: Mapping[str, RigMetrics], settings: ReportSettings) -> list[str]:
    """Which budget each rig's Table 1 rows ran at, read from their metrics files: one note per
    budget, naming the rigs that share it."""
    groups: dict[tuple, list[str]] = {}
    for rig, metrics in tree.items():
        for method in settings.methods_for(rig):
            extra = metrics.methods[method].extra
            budget = extra.get("budget") or {}
            key = (extra.get("experiment"), extra.get("frames_per_clip"), *sorted(budget.items()))
            if budget and rig not in groups.setdefault(key, []):
                groups[key].append(rig)
    notes = []
    for (experiment, first, *budget), rigs in groups.items():
        values = dict(budget)
        parts = [text.format(values[key]) for key, text in BUDGET_PHRASES if key in values]
        frames = "whole test clips" if first is None else f"the first {first} frames of a clip"
        where = frames if experiment is None else f"experiment {experiment}, {frames}"
        notes.append(
            f"Budget of {', '.join(rig_label(r) for r in rigs)} (from the metrics files): "
            f"{where}; {', '.join(parts)}."
        )
    return notes


MEAN_PREDICTOR = "mean"  # the method key of the yardstick row (conf/method/mean.yaml)


def _motion_numbers(result: LoadedResult, motion: str) -> Numbers:
    return result.average if motion == published.AVERAGE else result.clips[motion]


def _mean_predictor(metrics: RigMetrics, motion: str) -> Numbers | None:
    """The mean predictor's numbers on the same frames, if this run evaluated it."""
    result = metrics.methods.get(MEAN_PREDICTOR)
    return None if result is None else _motion_numbers(result, motion)


def _ratio(value: float, baseline: float | None) -> float | None:
    return None if baseline is None or baseline <= 0 else value / baseline


def _method_cells(
    numbers: Numbers, baseline: Numbers | None, spreads: dict[str, Spread | None]
) -> list[str]:
    """A row's cells: a network row's errors are the median over seeds, its min–max beside."""
    percent = numbers.joint_rms_percent_of_height
    relative = _ratio(numbers.joint_error, baseline and baseline.joint_error)
    joint, truth = spreads["joint_error"], spreads["ground_truth_error"]
    return [
        format_error(numbers.joint_error if joint is None else joint.median),
        _range_cell(joint),
        format_error(numbers.joint_rms),
        MISSING if percent is None else format_seconds(percent),
        MISSING if relative is None else format_error(relative),
        format_error(numbers.ground_truth_error if truth is None else truth.median),
        _range_cell(truth),
        format_seconds(numbers.total_time_s),
        format_seconds(numbers.fps),
    ]


def _row_spreads(metrics: RigMetrics, result: LoadedResult, motion: str) -> dict:
    """The row's joint and ground-truth errors over seeds (None: not a network row, or no
    replicate seed was run)."""
    clip = None if motion == published.AVERAGE else motion
    return {
        measure: row_spread(result, metrics.replicates, clip, measure)
        for measure in ("joint_error", "ground_truth_error")
    }


def _range_cell(spread: Spread | None) -> str:
    if spread is None:
        return MISSING
    return f"{format_error(spread.low)}–{format_error(spread.high)} ({spread.seeds})"


def _spread_record(numbers: Numbers, spreads: dict[str, Spread | None]) -> dict:
    """The csv's seed columns: median, min, max over seeds (seed 0 alone: 1 seed)."""
    record: dict[str, Any] = {}
    seeds = 1
    for measure, spread in spreads.items():
        if spread is None:
            spread = Spread.of([getattr(numbers, measure)])
        seeds = spread.seeds
        record |= {
            f"{measure}_median": spread.median,
            f"{measure}_min": spread.low,
            f"{measure}_max": spread.high,
        }
    return record | {"seeds": seeds}


#: the comparisons the report states between Table 1 rows (ours): (row, other row or a bar)
CLAIMS = (
    ("nn_joint_space", "gpr_computed_jacobian"),
    ("nn_joint_space_tuned", 0.5),  # the tuning's bar (docs/inverse-mappings.md, session 34)
)


def seed_notes(tree: Mapping[str, RigMetrics], settings: ReportSettings) -> list[str]:
    """Per rig run with replicate seeds: what its network cells show, then each claim of
    ``CLAIMS`` on the Average joint error, judged by the spread (a note each)."""
    notes = []
    for rig, metrics in tree.items():
        if not metrics.replicates:
            continue
        seeds = ", ".join(str(k) for k in (0, *metrics.replicates))
        notes.append(
            f"{rig_label(rig)}: network rows (trained guesses) were re-trained with seeds "
            f"{seeds}; their Joint and Ground Truth Error cells give the median over the seeds "
            "and the min–max beside (the csv: *_median, *_min, *_max and seeds, while "
            "joint_error stays seed 0's); their other columns are seed 0's."
        )
        for row, other in CLAIMS:
            claim = _claim(metrics, row, other, settings) if row in metrics.methods else None
            if claim:
                notes.append(f"{rig_label(rig)}, Average joint error: {claim}.")
    return notes


def _claim(
    metrics: RigMetrics, row: str, other: str | float, settings: ReportSettings
) -> str | None:
    if isinstance(other, str) and other not in metrics.methods:
        return None
    unit = f"{metrics.methods[row].length_unit}{SQUARE}"
    label = settings.catalogue.method(row).label
    if isinstance(other, str):
        other_label = settings.catalogue.method(other).label
        return compare(
            label, _average_spread(metrics, row), other_label, _average_spread(metrics, other), unit
        )
    return compare(label, _average_spread(metrics, row), "the bar", other, unit)


def _average_spread(metrics: RigMetrics, method: str) -> Spread:
    result = metrics.methods[method]
    spread = row_spread(result, metrics.replicates, None, "joint_error")
    return spread if spread is not None else Spread.of([result.average.joint_error])


def _relative_record(numbers: Numbers, baseline: Numbers | None) -> dict:
    """The scale-free numbers: RMS distance, % of height, errors ÷ the mean predictor's."""
    return {
        "joint_rms": numbers.joint_rms,
        "joint_rms_percent_of_height": numbers.joint_rms_percent_of_height,
        "joint_error_relative_to_mean": _ratio(
            numbers.joint_error, baseline and baseline.joint_error
        ),
        "ground_truth_error_relative_to_mean": _ratio(
            numbers.ground_truth_error, baseline and baseline.ground_truth_error
        ),
    }


def _paper_cells(paper: published.PublishedMethodRow | None) -> list[str]:
    if paper is None:
        return [MISSING] * 4
    return [paper.joint_error, paper.ground_truth_error, paper.total_time_s, paper.fps]


def _number_record(numbers: Numbers) -> dict:
    return {
        "frames": numbers.frames,
        "joint_error": numbers.joint_error,
        "ground_truth_error": numbers.ground_truth_error,
        "total_time_s": numbers.total_time_s,
        "fps": numbers.fps,
        "rig_evaluations": numbers.rig_evaluations,
    }


def _paper_record(paper: published.PublishedMethodRow | None) -> dict:
    keys = ("joint_error", "ground_truth_error", "total_time_s", "fps")
    if paper is None:
        return {f"published_{k}": "" for k in keys} | {"published_source": ""}
    values = {f"published_{k}": getattr(paper, k) for k in keys}
    source = f"{published.SOURCE}, Table 1 ({published.LABEL})"
    return values | {"published_source": source}


# --------------------------------------------------------------------------- Tables 2 and §7.1
def _per_rig_table(
    tree: Mapping[str, RigMetrics], settings: ReportSettings, spec: _PerRigSpec
) -> Table:
    """Rows = the ``spec``'s samplers or kernels; per rig of ``settings.sampler_rigs`` a group
    of Joint / Ground Truth Error; the spec's notes follow the two error notes."""
    tree = {rig: metrics for rig, metrics in tree.items() if rig in settings.sampler_rigs}
    keys, attribute = getattr(settings, spec.attribute), spec.attribute
    name, title, what, paper = spec.name, spec.title, spec.what, spec.paper
    notes = [JOINT_ERROR_NOTE, GROUND_TRUTH_NOTE, *spec.notes]
    first_column = "Method" if what == "sampler" else "Kernel"
    columns = [Column(first_column, numeric=False)]
    for rig, metrics in tree.items():
        unit = _unit_label({r.length_unit for r in getattr(metrics, attribute).values()})
        group = rig_label(rig)
        columns += [Column(f"Joint Error ({unit})", group), Column("Ground Truth Error", group)]
    if paper is not None:
        columns += [
            Column("Joint Error", published.LABEL, short_group="published"),
            Column("Ground Truth Error", published.LABEL, short_group="published"),
        ]
    rows, records = [], []
    for key in keys:
        row_kind = settings.catalogue.row(what, key)
        cells = [row_kind.display]
        for rig, metrics in tree.items():
            result: LoadedResult = getattr(metrics, attribute)[key]
            numbers = result.average
            cells += [format_error(numbers.joint_error), format_error(numbers.ground_truth_error)]
            record = {
                "rig": rig,
                what: key,
                f"{what}_label": row_kind.label,
                **_number_record(numbers),
                "length_unit": result.length_unit,
            }
            if paper is not None:  # a row the paper lacks (a new sampler) shows no number
                record |= {
                    "published_joint_error": paper.get(key, (None, None))[0],
                    "published_ground_truth_error": paper.get(key, (None, None))[1],
                    "published_source": f"{published.SOURCE}, Table 2 ({published.LABEL}; "
                    "character not stated)",
                }
            records.append(record)
        if paper is not None:
            cells += list(paper.get(key, (MISSING, MISSING)))
        rows.append(cells)
    return Table(
        name=name,
        title=title,
        columns=columns,
        rows=rows,
        data=pd.DataFrame.from_records(records),
        notes=notes,
    )


@dataclass(frozen=True)
class _PerRigSpec:
    """What a per-rig table compares: the settings list and metrics attribute it reads."""

    attribute: str  # "samplers" or "kernels": the ReportSettings list and RigMetrics field
    what: str  # the catalogue's kind of row: sampler or kernel
    name: str
    title: str
    paper: Mapping[str, tuple[str, str]] | None
    notes: tuple[str, ...]


_SAMPLING = _PerRigSpec(
    "samplers",
    "sampler",
    "table2_sampling",
    "Table 2 — the network trained with each supersampling method (Average of the test clips)",
    published.TABLE2,
    (
        "'No Extra Samples' trains on the animator corpus alone; the others add the same "
        "number of supersampled poses (budget.samples) drawn by each strategy (§5.2).",
        PUBLISHED_NOTE + " The paper does not say which character Table 2 was measured on.",
    ),
)
_KERNELS = _PerRigSpec(
    "kernels",
    "kernel",
    "table_kernels",
    "GPR kernels (§7.1) — Average of the test clips",
    None,
    (
        "The paper reports no numbers for this comparison, only that the multiquadric "
        "kernel did best (§7.1).",
    ),
)


def sampling_table(tree: Mapping[str, RigMetrics], settings: ReportSettings) -> Table:
    """Table 2: the network trained on the corpus plus each sampler's supersamples."""
    return _per_rig_table(tree, settings, _SAMPLING)


def kernels_table(tree: Mapping[str, RigMetrics], settings: ReportSettings) -> Table:
    """§7.1: GPR on the train corpus with each kernel (no published numbers exist)."""
    return _per_rig_table(tree, settings, _KERNELS)


# --------------------------------------------------------------------------- Table 3
BLEND_FILE_PREFIX = "blend_file:"  # the name rig=blend_file gives a user's file


def rigs_table(facts: Sequence[RigFacts]) -> Table:
    """Table 3: training frames, rig DOFs (all and used) and joint DOFs per character."""
    columns = [Column("Character", numeric=False)]
    columns += [
        Column(label, OURS, short_group="")
        for label in (
            "Training Frames",
            "Keyed Frames",
            "Rig DOFs",
            "Used Rig DOFs",
            "Joint DOFs",
        )
    ]
    columns.append(Column("Character", published.LABEL, numeric=False, short_group="published"))
    columns += [
        Column(label, published.LABEL, short_group="published")
        for label in ("Training Frames", "Rig DOFs", "Joint DOFs")
    ]
    rows, records = [], []
    for fact in facts:
        paper = published.TABLE3.get(fact.rig)
        ours = [
            fact.training_frames,
            fact.keyed_frames,
            fact.rig_dofs,
            fact.used_rig_dofs,
            fact.joint_dofs,
        ]
        rows.append([rig_label(fact.rig), *map(str, ours), *(paper if paper else [MISSING] * 4)])
        records.append(
            {
                "rig": fact.rig,
                "training_frames": fact.training_frames,
                "keyed_frames": fact.keyed_frames,
                "rig_dofs": fact.rig_dofs,
                "used_rig_dofs": fact.used_rig_dofs,
                "joint_dofs": fact.joint_dofs,
                "length_unit": fact.length_unit,
                "backend": fact.backend,
                "published_character": paper[0] if paper else "",
                "published_training_frames": paper[1] if paper else "",
                "published_rig_dofs": paper[2] if paper else "",
                "published_joint_dofs": paper[3] if paper else "",
                "published_source": f"{published.SOURCE}, Table 3 ({published.LABEL})"
                if paper
                else "",
            }
        )
    notes = [
        "Training Frames: every played frame of the train corpus (keys and the frames "
        "interpolated between them); Keyed Frames: frames holding at least one key.",
        "Rig DOFs: all controls of the rig; Used Rig DOFs: those the animators key, the "
        "only ones learning and refinement touch (§6.1).",
        "Joint DOFs: 3 × joints (3 × mesh vertices for mesh rigs).",
    ]
    blender = [rig_label(f.rig) for f in facts if f.backend == "blender"]
    own = [rig_label(f.rig) for f in facts if f.rig.startswith(BLEND_FILE_PREFIX)]
    if blender:
        notes.append(
            f"{', '.join(blender)}: Blender rigs (not in the paper). Rig DOFs count every "
            "transform channel of the control bones and every custom property, face and paw "
            "digits included; Joint DOFs are 3 × the deform-bone heads the rig's config keeps "
            "(the built-in Rigify rigs without the face and the paw digits"
            + (f"; {', '.join(own)}: every deform bone" if own else "")
            + ")."
        )
    if own:
        notes.append(
            f"{', '.join(own)}: a user's own .blend (rig=blend_file), named after the file; its "
            "corpus is the file's actions and its used controls the ones they key."
        )
    return Table(
        name="table3_rigs",
        title="Table 3 — numerical characteristics of the rigs",
        columns=columns,
        rows=rows,
        data=pd.DataFrame.from_records(records),
        notes=[*notes, PUBLISHED_NOTE, published.TABLE3_NOTE],
    )


# --------------------------------------------------------------------------- splits (ours)
SPLITS_NOTE = (
    "Training: the method on its own training-corpus frames (its training error). Held-out: "
    "the training motions played again with other seeds (new takes of what the mapping "
    "learned from: in distribution). Test: the library's test clips, extreme on purpose (most "
    "of their frames lie outside the corpus). Held-out ÷ Training near 1 means the mapping "
    "generalises within its corpus; a large ratio means it memorised the training frames."
)


def splits_table(tree: Mapping[str, RigMetrics], settings: ReportSettings) -> Table | None:
    """Joint error (and ground truth) of each method scored on train, held-out and test."""
    rows, records = [], []
    for rig, metrics in tree.items():
        train, heldout = metrics.splits.get("train", {}), metrics.splits.get("heldout", {})
        for method in [m for m in settings.methods_for(rig) if m in train and m in heldout]:
            test = metrics.methods.get(method)
            numbers = [train[method].average, heldout[method].average]
            numbers.append(test.average if test is not None else None)
            ratio = _ratio(numbers[1].joint_error, numbers[0].joint_error)
            label = settings.catalogue.method(method).display
            cells = [rig_label(rig), label]
            cells += [MISSING if n is None else format_error(n.joint_error) for n in numbers]
            cells += [MISSING if ratio is None else format_seconds(ratio)]
            cells += [MISSING if n is None else format_error(n.ground_truth_error) for n in numbers]
            rows.append(cells)
            record = {"rig": rig, "method": method, "heldout_over_train_joint_error": ratio}
            for split, n in zip(("train", "heldout", "test"), numbers, strict=True):
                record |= {
                    f"{split}_frames": None if n is None else n.frames,
                    f"{split}_joint_error": None if n is None else n.joint_error,
                    f"{split}_ground_truth_error": None if n is None else n.ground_truth_error,
                }
            records.append(record)
    if not rows:
        return None
    unit = _unit_label({r.length_unit for m in tree.values() for r in m.methods.values()})
    columns = [Column("Character", numeric=False), Column("Method", numeric=False)]
    columns += [
        Column(f"{split} ({unit})", "Joint Error", short_group="joint")
        for split in ("Training", "Held-out", "Test")
    ]
    columns += [Column("Held-out ÷ Training", "Joint Error", short_group="joint")]
    columns += [
        Column(split, "Ground Truth Error", short_group="truth")
        for split in ("Training", "Held-out", "Test")
    ]
    return Table(
        name="table_splits",
        title="In distribution and out: the regression rows on training, held-out and test frames",
        columns=columns,
        rows=rows,
        data=pd.DataFrame.from_records(records),
        notes=[SPLITS_NOTE, JOINT_ERROR_NOTE, GROUND_TRUTH_NOTE],
    )
