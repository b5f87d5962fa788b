"""The whole report from the metrics tree: four tables, the figures and ``index.html``.

Outputs (the report stage owns exactly these)::

    <reports>/index.html
    <reports>/tables/{table1_methods,table2_sampling,table3_rigs,table_kernels}.{md,csv,html}
    <reports>/figures/results/*.png

Supersample grids ``<reports>/figures/samples_<rig>.png`` belong to another stage;
the index links them when they exist.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from rigmap.reports.catalog import rig_label
from rigmap.reports.edits_tables import edits_tables
from rigmap.reports.figures import (
    FigureFile,
    confidence_figure,
    per_frame_figure,
    sweep_figure,
    time_figure,
)
from rigmap.reports.index_page import sample_grid_figures, write_index
from rigmap.reports.latent_tables import latent_figures, latent_tables
from rigmap.reports.mapping_tables import mocap_table, partial_table
from rigmap.reports.metrics_tree import SWEEP_FOLDER, load_metrics
from rigmap.reports.path_tables import path_figures, path_table
from rigmap.reports.rig_facts import rig_facts
from rigmap.reports.settings import ReportSettings
from rigmap.reports.simulation_tables import simulation_figures, simulation_table
from rigmap.reports.table import Table, write_table
from rigmap.reports.tables import (
    kernels_table,
    methods_table,
    rigs_table,
    sampling_table,
    splits_table,
)
from rigmap.store.layout import Layout


@dataclass
class ReportFiles:
    """What ``build_report`` wrote, and the notes it put on the index page."""

    index: Path
    tables: dict[str, dict[str, Path]]
    figures: list[FigureFile]
    notes: list[str] = field(default_factory=list)


def file_stem(rig: str) -> str:
    """A rig name fit for a file name and a link (``blend_file:hero`` -> ``blend_file_hero``)."""
    return rig.replace(":", "_")


def _load_rig(name: str, data_root: Path | None = None):
    """A rig by name; a user's .blend (``blend_file:<stem>``) from the options its corpus
    import recorded (``<data>/<rig>/corpus/blend_import.json``: file, controls, ranges)."""
    from rigmap.rigs import load

    if data_root is not None:
        from rigmap.animation.blend_corpus import IMPORT_FILE

        imported = Layout(data=data_root).corpus_folder(name) / IMPORT_FILE
        if imported.is_file():
            return load(json.loads(imported.read_text())["rig_config"])
    return load(name)


def every_rigs_facts(rigs, data_root: Path, load_rig: Callable[[str], object]) -> list:
    """Table 3's numbers of each rig, from the rig and its train corpus (workers closed)."""
    facts = []
    for name in rigs:
        rig = load_rig(name)
        try:
            facts.append(rig_facts(rig, Layout(data=data_root).corpus(name, "train")))
        finally:
            getattr(rig, "close", lambda: None)()  # a Blender rig's workers
    return facts


def build_report(
    *,
    metrics_root: str | Path,
    data_root: str | Path,
    reports_root: str | Path,
    settings: ReportSettings | None = None,
    load_rig: Callable[[str], object] | None = None,
) -> ReportFiles:
    """Read every metrics file the settings expect, then write tables, figures and the index.

    Nothing is written until every input has been read and checked, so a missing file
    leaves the previous report untouched.
    """
    settings = settings or ReportSettings()
    metrics_root, data_root, reports_root = map(Path, (metrics_root, data_root, reports_root))
    layout = Layout(data=data_root, metrics=metrics_root, reports=reports_root)
    tree = load_metrics(metrics_root, data_root, settings)
    facts = every_rigs_facts(
        settings.rigs, data_root, load_rig or functools.partial(_load_rig, data_root=data_root)
    )
    for metrics in tree.values():  # read every per-frame CSV before writing anything
        for method in settings.methods_for(metrics.rig):
            metrics.methods[method].per_frame()

    tables = _tables(tree, facts, settings, metrics_root)
    written_tables = {t.name: write_table(t, layout.tables()) for t in tables}

    figures_folder = layout.result_figures()
    method_tree = {rig: tree[rig] for rig in settings.method_rigs}
    figures = [
        per_frame_figure(tree[rig], settings, figures_folder / f"per_frame_{file_stem(rig)}.png")
        for rig in settings.method_rigs
    ]
    figures.append(time_figure(method_tree, settings, figures_folder / "time_per_method.png"))
    confidence = confidence_figure(tree, settings, figures_folder / "confidence.png")
    if confidence is not None:
        figures.append(confidence)
    notes = []
    sweep = sweep_figure(tree, figures_folder / "joint_error_vs_supersamples.png")
    if sweep is None:
        notes.append(
            "Joint error against the number of supersamples: no samples sweep was evaluated "
            f"(expected {metrics_root}/<rig>/{SWEEP_FOLDER}/nn-<sampler>-<samples>.json); the "
            "figure is skipped."
        )
    else:
        figures.append(sweep)
    _remove_stale_figures(figures_folder, {f.path.resolve() for f in figures})
    grids, grid_notes = sample_grid_figures(layout.figures(), settings.sampler_rigs)
    grids += latent_figures(layout.figures())  # the latent stages' Fig 2
    grids += path_figures(layout.figures())  # the map_path stage's Fig 7, when it ran
    grids += simulation_figures(layout.figures())  # the simulate stage's Fig 9, when it ran
    notes += grid_notes

    index = write_index(
        layout.index_page(),
        tables=[(t, written_tables[t.name]) for t in tables],
        result_figures=figures,
        sample_grids=grids,
        notes=notes,
        facts={
            "Characters": ", ".join(rig_label(r) for r in settings.rigs),
            "Methods compared (Table 1) on": ", ".join(rig_label(r) for r in settings.method_rigs),
            "Test clips": "; ".join(
                f"{rig_label(r)}: {', '.join(tree[r].test_clips)}" for r in settings.rigs
            ),
            "Network rows (Table 1) trained with sampler": settings.nn_sampler,
            "Metrics read from": str(metrics_root),
        },
    )
    return ReportFiles(index=index, tables=written_tables, figures=[*figures, *grids], notes=notes)


def _tables(tree: dict, facts: list, settings: ReportSettings, metrics_root: Path) -> list[Table]:
    """The report's tables: the paper's four, then those of the stages that ran."""
    tables: list[Table] = [
        methods_table(tree, settings),
        sampling_table(tree, settings),
        rigs_table(facts),
        kernels_table(tree, settings),
    ]
    splits = splits_table(tree, settings)
    if splits is not None:  # only when the evaluate_splits stage ran
        tables.append(splits)
    # the mapping stages' tables, when map_mocap and map_partial ran
    tables += [t for t in (mocap_table(metrics_root), partial_table(metrics_root)) if t]
    tables += [t for t in (path_table(metrics_root),) if t]  # when map_path ran (Fig 7)
    tables += [t for t in (simulation_table(metrics_root),) if t]  # when simulate ran (Fig 9)
    tables += latent_tables(metrics_root)  # when the latent stages ran (#18)
    tables += edits_tables(metrics_root)  # when the edit stages ran (#17)
    return tables


def _remove_stale_figures(folder: Path, keep: set[Path]) -> None:
    """PNGs an earlier report left in the report's own figure folder (e.g. a dropped rig)."""
    for path in folder.glob("*.png"):
        if path.resolve() not in keep:
            path.unlink()
