"""The report's figures: per-frame joint error, time per method, error against supersamples.

Figures are ``matplotlib.figure.Figure`` objects (no pyplot state) saved
atomically with :func:`rigmap.viz.atomic.save_figure`. Errors span orders of
magnitude between the script and refined methods, so they are drawn on log
axes; exact zeros are lifted to a floor a decade below the smallest positive
value and the floor is said on the axis.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from rigmap.catalog import default_catalogue
from rigmap.reports.catalog import rig_label
from rigmap.reports.metrics_tree import RigMetrics
from rigmap.reports.settings import ReportSettings
from rigmap.viz.atomic import save_figure

DPI = 110


@dataclass(frozen=True)
class FigureFile:
    """A written figure and the caption the index shows under it."""

    path: Path
    caption: str


def stage_figures(figures_folder: str | Path, prefix: str, caption: str) -> list[FigureFile]:
    """The figure a stage drew for each rig it ran on (``<prefix>_<rig>.png``), each captioned
    ``<rig label>: <caption>``; none when the stage did not run."""
    found = sorted(Path(figures_folder).glob(f"{prefix}_*.png"))
    return [FigureFile(p, f"{rig_label(p.stem[len(prefix) + 1 :])}: {caption}") for p in found]


def _method_colors(methods, catalogue) -> dict[str, tuple]:
    """A colour per method, fixed by its place in the catalogue (uncatalogued ones after)."""
    from matplotlib import colormaps

    palette = colormaps["tab10"]
    order = [m.key for m in catalogue.methods]
    order += [m for m in methods if m not in order]
    return {m: palette(order.index(m) % 10) for m in methods}


def _positive_floor(values: np.ndarray) -> float:
    positive = values[values > 0]
    return float(positive.min()) / 10 if positive.size else 1e-12


def per_frame_figure(metrics: RigMetrics, settings: ReportSettings, out: str | Path) -> FigureFile:
    """One panel per test clip, one line per method: joint error on every frame (log scale)."""
    methods = settings.methods_for(metrics.rig)
    tables = {m: metrics.methods[m].per_frame() for m in methods}
    clips = metrics.test_clips
    columns = min(3, len(clips))
    rows = math.ceil(len(clips) / columns)
    fig = Figure(figsize=(5.2 * columns, 3.6 * rows + 0.9), dpi=DPI, layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False)
    everything = np.concatenate([t["joint_error"].to_numpy(float) for t in tables.values()])
    floor = _positive_floor(everything)
    colors = _method_colors(methods, settings.catalogue)
    unit = metrics.length_unit
    for index, clip in enumerate(clips):
        ax = axes[index // columns][index % columns]
        for method in methods:
            rows_of_clip = tables[method][tables[method]["clip"] == clip]
            label = settings.catalogue.method(method).display
            ax.plot(
                rows_of_clip["frame"].to_numpy(),
                np.maximum(rows_of_clip["joint_error"].to_numpy(float), floor),
                label=label,
                color=colors[method],
                linewidth=1.2,
                linestyle="--" if settings.catalogue.method(method).extra else "-",
            )
        ax.set_yscale("log")
        ax.set_title(clip, fontsize=10)
        ax.set_xlabel("frame")
        ax.set_ylabel(f"joint error ({unit}²)")
        ax.grid(True, which="major", alpha=0.3)
    for index in range(len(clips), rows * columns):
        axes[index // columns][index % columns].set_visible(False)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=4, fontsize=8, frameon=False)
    title = (
        f"{rig_label(metrics.rig)}: joint error per frame (log scale; zeros drawn at "
        f"{floor:.1e} {unit}²)"
    )
    caption = (
        f"{rig_label(metrics.rig)}: per-frame joint error of every method on each test clip "
        "(from the per-frame CSVs)."
    )
    return _finished(fig, out, title, caption)


def time_figure(
    tree: Mapping[str, RigMetrics], settings: ReportSettings, out: str | Path
) -> FigureFile:
    """Frames per second of each method on each rig (log scale), total seconds annotated."""
    rigs = list(tree)
    height = 1.0 + 0.42 * len(settings.catalogue.methods) * len(rigs)
    fig = Figure(figsize=(11, height), dpi=DPI, layout="constrained")
    axes = fig.subplots(len(rigs), 1, squeeze=False)[:, 0]
    for ax, rig in zip(axes, rigs, strict=True):
        methods = settings.methods_for(rig)
        colors = _method_colors(methods, settings.catalogue)
        fps = [tree[rig].methods[m].average.fps for m in methods]
        seconds = [tree[rig].methods[m].average.total_time_s for m in methods]
        labels = [settings.catalogue.method(m).display for m in methods]
        positions = np.arange(len(methods))[::-1]
        ax.barh(positions, fps, color=[colors[m] for m in methods])
        ax.set_xscale("log")
        ax.set_yticks(positions, labels, fontsize=8)
        ax.set_xlim(min(fps) / 3, max(fps) * 20)
        for y, value, total in zip(positions, fps, seconds, strict=True):
            ax.annotate(
                f"{value:.3g} fps, {total:.3g} s",
                (value, y),
                xytext=(4, 0),
                textcoords="offset points",
                va="center",
                fontsize=7,
            )
        frames = tree[rig].methods[methods[0]].average.frames
        ax.set_title(f"{rig_label(rig)} ({frames} test frames)", fontsize=10)
        ax.grid(True, axis="x", which="major", alpha=0.3)
    axes[-1].set_xlabel("frames per second (log scale)")
    caption = (
        "Frames per second of each method (log scale) with its total wall-clock seconds over "
        "all test clips."
    )
    return _finished(
        fig, out, "Speed of each method: frames per second over all test frames", caption
    )


def sweep_figure(tree: Mapping[str, RigMetrics], out: str | Path) -> FigureFile | None:
    """Joint error against the number of supersamples, if a samples sweep was evaluated."""
    rigs = [rig for rig, metrics in tree.items() if metrics.sweep or metrics.joint_space_sweep]
    if not rigs:
        return None
    fig = Figure(figsize=(5.5 * len(rigs), 4.2), dpi=DPI, layout="constrained")
    axes = fig.subplots(1, len(rigs), squeeze=False)[0]
    palette = _sampler_colors()
    for ax, rig in zip(axes, rigs, strict=True):
        metrics = tree[rig]
        for sampler, points in metrics.sweep.items():
            counts = np.array([n for n in points if n > 0])
            errors = np.array([points[n].average.joint_error for n in counts])
            label = default_catalogue().sampler(sampler).label
            ax.plot(counts, errors, marker="o", label=label, color=palette.get(sampler))
        if metrics.joint_space_sweep:  # its own draws (issue #15), beside the samplers' curves
            draws = np.array(list(metrics.joint_space_sweep))
            errors = np.array([p.average.joint_error for p in metrics.joint_space_sweep.values()])
            label = "Joint-space NN (its own draws)"
            ax.plot(draws, errors, marker="s", linestyle="-.", color="black", label=label)
        baseline = metrics.samplers.get("none")
        if baseline is not None:
            ax.axhline(
                baseline.average.joint_error,
                color="grey",
                linestyle="--",
                label="No Extra Samples",
            )
        ax.set_xscale("log")
        # label the counts that were run, not log-scale minor ticks (they overlap)
        counts_run = sorted(
            {n for points in metrics.sweep.values() for n in points if n > 0}
            | set(metrics.joint_space_sweep)
        )
        ax.set_xticks(counts_run, [f"{n:,}" for n in counts_run])
        if metrics.joint_space_sweep and metrics.sweep:  # two sets of counts: labels crowd
            ax.tick_params(axis="x", labelrotation=45)
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("extra supersampled poses")
        ax.set_ylabel(f"joint error ({metrics.length_unit}²)")
        ax.set_title(rig_label(rig), fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8)
    caption = (
        "Joint error of the network (Average of the test clips) against the number of extra "
        "supersampled poses it was trained with; the joint-space network's curve counts the "
        "poses it draws itself (around the corpus and wide over the soft ranges)."
    )
    return _finished(
        fig, out, "The network's joint error against the number of supersamples", caption
    )


def confidence_figure(
    tree: Mapping[str, RigMetrics], settings: ReportSettings, out: str | Path
) -> FigureFile | None:
    """Per-frame joint error against novelty (the per-frame confidence), one panel per rig and
    unrefined regression method, Spearman's ρ in each title; None if no file has novelty."""
    panels = [
        (rig, method, table)
        for rig in settings.method_rigs
        for method in settings.methods_for(rig)
        if tree[rig].methods[method].extra.get("refine") == "none"
        and "novelty" in (table := tree[rig].methods[method].per_frame())
    ]
    if not panels:
        return None
    rigs = list(dict.fromkeys(rig for rig, _, _ in panels))
    columns = max(sum(1 for r, _, _ in panels if r == rig) for rig in rigs)
    fig = Figure(figsize=(3.6 * columns, 3.2 * len(rigs) + 0.6), dpi=DPI, layout="constrained")
    axes = fig.subplots(len(rigs), columns, squeeze=False)
    used = set()
    for rig, method, table in panels:
        row = rigs.index(rig)
        column = sum(1 for r, _ in used if r == rig)
        used.add((rig, method))
        ax = axes[row][column]
        novelty, error = table["novelty"].to_numpy(float), table["joint_error"].to_numpy(float)
        rho = tree[rig].methods[method].novelty_spearman
        ax.scatter(
            np.maximum(novelty, _positive_floor(novelty)),
            np.maximum(error, _positive_floor(error)),
            s=6,
            alpha=0.6,
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        label = settings.catalogue.method(method).label
        shown = "n/a" if rho is None else f"{rho:.2f}"
        ax.set_title(f"{rig_label(rig)} — {label} (Spearman ρ {shown})", fontsize=9)
        ax.set_xlabel(f"novelty ({tree[rig].length_unit}, RMS to the nearest learned frames)")
        ax.set_ylabel(f"joint error ({tree[rig].length_unit}²)")
        ax.grid(True, which="major", alpha=0.3)
    for row, rig in enumerate(rigs):
        for column in range(sum(1 for r, _ in used if r == rig), columns):
            axes[row][column].set_visible(False)
    caption = (
        "Per-frame confidence: each test frame's joint error against its novelty, the mean RMS "
        "joint distance of its input to the 5 nearest frames the method learned from (the "
        "training corpus; for the joint-space network also its own drawn poses; higher = less "
        "confident); frames far from those are the ones to check."
    )
    return _finished(fig, out, "Joint error against novelty, per test frame", caption)


def _finished(fig, out: str | Path, title: str, caption: str) -> FigureFile:
    """Title the figure, save it atomically, and pair it with its caption."""
    fig.suptitle(title, fontsize=11)
    return FigureFile(save_figure(fig, out, dpi=DPI), caption)


def _sampler_colors() -> dict[str, tuple]:
    from matplotlib import colormaps

    palette = colormaps["Dark2"]
    return {row.key: palette(index) for index, row in enumerate(default_catalogue().samplers)}
