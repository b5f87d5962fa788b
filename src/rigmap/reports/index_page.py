"""``reports/index.html``: every table inline, every figure as an image, links to the files.

Plain HTML and a little CSS (no scripts) so it opens from disk, in CI artefacts
and in any browser. All links are relative to the page's folder.
"""

from __future__ import annotations

import html
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from rigmap.evaluation.metrics import write_text_atomically
from rigmap.reports.catalog import rig_label
from rigmap.reports.figures import FigureFile
from rigmap.reports.table import Table, html_page, to_html_fragment


def _link(target: Path, page_folder: Path) -> str:
    return Path(os.path.relpath(target, page_folder)).as_posix()


def _figure(figure: FigureFile, page_folder: Path) -> str:
    source = html.escape(_link(figure.path, page_folder))
    caption = html.escape(figure.caption)
    return (
        f'<figure><a href="{source}"><img src="{source}" alt="{caption}"></a>'
        f"<figcaption>{caption}</figcaption></figure>\n"
    )


def write_index(
    out: str | Path,
    *,
    tables: Sequence[tuple[Table, Mapping[str, Path]]],
    result_figures: Sequence[FigureFile],
    sample_grids: Sequence[FigureFile],
    notes: Sequence[str],
    facts: Mapping[str, str],
) -> Path:
    """Write the index page; ``facts`` are label/value lines shown under the title."""
    out = Path(out)
    folder = out.parent
    esc = html.escape
    title = "Learning Inverse Rig Mappings by Nonlinear Regression"
    body = [f"<h1>rigmap — reproducing <i>{title}</i></h1>\n"]
    body.append("<ul>\n")
    body += [f"<li>{esc(label)}: {esc(value)}</li>\n" for label, value in facts.items()]
    body.append("</ul>\n")
    body.append("<h2>Contents</h2>\n<ul>\n")
    for table, _files in tables:
        body.append(f'<li><a href="#{esc(table.name)}">{esc(table.title)}</a></li>\n')
    body.append('<li><a href="#figures">Figures</a></li>\n</ul>\n')
    for note in notes:
        body.append(f'<p class="note">{esc(note)}</p>\n')

    for table, files in tables:
        links = " · ".join(
            f'<a href="{esc(_link(path, folder))}">{esc(kind.upper())}</a>'
            for kind, path in files.items()
        )
        body.append(f"<h2>{esc(table.title)}</h2>\n<p>Files: {links}</p>\n")
        body.append(to_html_fragment(table))

    body.append('<h2 id="figures">Figures</h2>\n')
    body += [_figure(figure, folder) for figure in result_figures]
    if sample_grids:
        body.append("<h3>Supersamples of each strategy (the paper's Fig. 4)</h3>\n")
        body += [_figure(figure, folder) for figure in sample_grids]
    page = html_page("rigmap report", "".join(body))
    return write_text_atomically(out, page)


def sample_grid_figures(figures_folder: Path, rigs: Sequence[str]) -> tuple[list, list[str]]:
    """The supersample grids ``samples_<rig>.png`` that exist, and a note for each absent one."""
    found, absent = [], []
    for rig in rigs:
        path = figures_folder / f"samples_{rig}.png"
        if path.is_file():
            caption = f"{rig_label(rig)}: random supersamples of each strategy, one row each."
            found.append(FigureFile(path, caption))
        else:
            absent.append(rig)
    notes = []
    if absent:
        notes.append(
            "Supersample grids (Fig. 4) not found for "
            + ", ".join(rig_label(r) for r in absent)
            + f" — expected {figures_folder}/samples_<rig>.png (the sample figures stage)."
        )
    return found, notes
