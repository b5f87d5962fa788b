"""A report table and its three renderings: Markdown, CSV and HTML.

A table keeps two views of the same content: ``rows`` of display strings
(numbers rounded like the paper's, grouped headers) for Markdown and HTML, and
``data``, a tidy frame at full precision with one column per quantity, for the
CSV a script reads back. Files are written atomically.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from rigmap.evaluation.metrics import write_text_atomically

MISSING = "—"


@dataclass(frozen=True)
class Column:
    """A display column; ``group`` heads several columns (a rig, or the published values)."""

    label: str
    group: str | None = None
    numeric: bool = True
    short_group: str | None = None  # how Markdown's single header row names the group

    @property
    def flat_label(self) -> str:
        group = self.short_group if self.short_group is not None else self.group
        return f"{group} · {self.label}" if group else self.label


@dataclass
class Table:
    """``name`` is the file stem; ``row_classes`` are CSS classes per row (``extra``, ...)."""

    name: str
    title: str
    columns: list[Column]
    rows: list[list[str]]
    data: pd.DataFrame
    notes: list[str] = field(default_factory=list)
    row_classes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        width = len(self.columns)
        for index, row in enumerate(self.rows):
            if len(row) != width:
                raise ValueError(
                    f"table {self.name}: row {index} has {len(row)} cells, expected {width}"
                )
        if not self.row_classes:
            self.row_classes = [""] * len(self.rows)
        if len(self.row_classes) != len(self.rows):
            raise ValueError(
                f"table {self.name}: {len(self.row_classes)} row classes for {len(self.rows)} rows"
            )


# --------------------------------------------------------------------------- numbers
def format_error(value: float) -> str:
    """Errors like the paper (3 decimals); tiny non-zero ones in scientific notation."""
    return _format_number(value, decimals=3)


def format_seconds(value: float) -> str:
    """Seconds and frames per second with 2 decimals (scientific below 0.005)."""
    return _format_number(value, decimals=2)


def _format_number(value: float, *, decimals: int) -> str:
    """``decimals`` places; non-zero values that would round to zero in scientific notation."""
    if value is None or not math.isfinite(value):
        return MISSING
    if value != 0 and abs(value) < 0.5 * 10.0**-decimals:
        return f"{value:.2e}"
    return f"{value:.{decimals}f}"


# --------------------------------------------------------------------------- renderings
def to_markdown(table: Table) -> str:
    header = [_md_cell(c.flat_label) for c in table.columns]
    align = ["---:" if c.numeric else ":---" for c in table.columns]
    lines = [f"## {table.title}", ""]
    lines.append("| " + " | ".join(header) + " |")
    lines.append("| " + " | ".join(align) + " |")
    for row in table.rows:
        lines.append("| " + " | ".join(_md_cell(cell) for cell in row) + " |")
    if table.notes:
        lines.append("")
        lines.extend(f"- {note}" for note in table.notes)
    return "\n".join(lines) + "\n"


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def to_html_fragment(table: Table) -> str:
    """The ``<table>`` with a caption and notes (for the index page and the table's own page)."""
    esc = html.escape
    grouped = any(c.group for c in table.columns)
    out = [
        f'<table class="results" id="{esc(table.name)}">',
        f"<caption>{esc(table.title)}</caption>",
    ]
    out.append("<thead>")
    if grouped:
        first, second = [], []
        index = 0
        while index < len(table.columns):
            column = table.columns[index]
            if column.group is None:
                first.append(f'<th rowspan="2">{esc(column.label)}</th>')
                index += 1
                continue
            span = 1
            while (
                index + span < len(table.columns)
                and table.columns[index + span].group == column.group
            ):
                span += 1
            css = ' class="published"' if "published" in column.group else ""
            first.append(f'<th colspan="{span}"{css}>{esc(column.group)}</th>')
            second += [f"<th{css}>{esc(c.label)}</th>" for c in table.columns[index : index + span]]
            index += span
        out.append("<tr>" + "".join(first) + "</tr>")
        out.append("<tr>" + "".join(second) + "</tr>")
    else:
        out.append("<tr>" + "".join(f"<th>{esc(c.label)}</th>" for c in table.columns) + "</tr>")
    out.append("</thead>")
    out.append("<tbody>")
    for row, css in zip(table.rows, table.row_classes, strict=True):
        cells = []
        for column, cell in zip(table.columns, row, strict=True):
            classes = []
            if column.numeric:
                classes.append("num")
            if column.group and "published" in column.group:
                classes.append("published")
            attribute = f' class="{" ".join(classes)}"' if classes else ""
            cells.append(f"<td{attribute}>{esc(str(cell))}</td>")
        row_attribute = f' class="{esc(css)}"' if css else ""
        out.append(f"<tr{row_attribute}>" + "".join(cells) + "</tr>")
    out.append("</tbody>")
    out.append("</table>")
    if table.notes:
        out.append('<ul class="notes">')
        out.extend(f"<li>{esc(note)}</li>" for note in table.notes)
        out.append("</ul>")
    return "\n".join(out) + "\n"


STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 78em; color: #222;
       padding: 0 1em; line-height: 1.4; }
h1, h2, h3 { font-weight: 600; }
table.results { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
table.results caption { text-align: left; font-weight: 600; padding: 0.3em 0; }
table.results th, table.results td { border: 1px solid #ccc; padding: 0.25em 0.6em; }
table.results th { background: #f0f0f0; }
table.results td.num { text-align: right; font-variant-numeric: tabular-nums; }
table.results .published { background: #f6f3ea; color: #555; font-style: italic; }
table.results tr.extra td { color: #555; }
table.results tr.average td { font-weight: 600; }
table.results tr.group-start td { border-top: 2px solid #888; }
ul.notes { font-size: 0.85em; color: #555; }
figure { margin: 1.5em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #444; }
p.note { color: #7a4b00; background: #fff8e6; padding: 0.4em 0.8em;
         border-left: 3px solid #e0a800; }
"""


def html_page(title: str, body: str) -> str:
    """A plain HTML page with the report's small stylesheet."""
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n"
        f"<body>\n{body}</body>\n</html>\n"
    )


def write_table(table: Table, folder: str | Path) -> dict[str, Path]:
    """``<name>.md``, ``<name>.csv`` and ``<name>.html`` in ``folder``, each atomically."""
    folder = Path(folder)
    page = html_page(table.title, f"<h1>{html.escape(table.title)}</h1>\n{to_html_fragment(table)}")
    return {
        "md": write_text_atomically(folder / f"{table.name}.md", to_markdown(table)),
        "csv": write_text_atomically(
            folder / f"{table.name}.csv", table.data.to_csv(index=False, lineterminator="\n")
        ),
        "html": write_text_atomically(folder / f"{table.name}.html", page),
    }
