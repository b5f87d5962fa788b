"""The paper's published numbers (Holden, Saito, Komura 2017, Tables 1-3), transcribed.

They were measured on the authors' Maya characters — other rigs, other
animation, other length units, a 2017 laptop — so they sit beside ours for
orientation only, never as a target. Values are kept as the strings the paper
prints (``"0.56"``, ``"9.3"``, ``"0.240"``) so nothing is rounded or padded in
transcription; ``as_number`` converts one when a figure needs it.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from importlib import resources

SOURCE = "Holden, Saito & Komura 2017"
TABLE1_FILE = "published_table1.csv"
LABEL = "published (Maya rigs, different characters and units)"


@dataclass(frozen=True)
class PublishedMethodRow:
    """One row of the paper's Table 1."""

    character: str  # our rig key
    motion: str  # the paper's clip name, or "Average"
    method: str  # our method key
    paper_method: str  # the label the paper prints
    joint_error: str
    ground_truth_error: str
    total_time_s: str
    fps: str


AVERAGE = "Average"

_PAPER_METHODS = {
    "Maya Script": "script",
    "GPR": "gpr",
    "GPR & Learned Jacobian": "gpr_learned_jacobian",
    "GPR & Computed Jacobian": "gpr_computed_jacobian",
    "NN": "nn",
    "NN & Computed Jacobian": "nn_computed_jacobian",
}


def _read_table1() -> tuple[PublishedMethodRow, ...]:
    """Table 1 as transcribed in ``reports/data/published_table1.csv`` (our rig key, the
    paper's motion and method labels, then its four printed numbers, kept as strings)."""
    text = resources.files("rigmap.reports").joinpath("data", TABLE1_FILE).read_text("utf-8")
    rows = []
    for number, line in enumerate(csv.DictReader(io.StringIO(text)), start=2):
        if None in line or None in line.values():
            raise ValueError(f"{TABLE1_FILE}: line {number} does not have the header's 7 fields")
        paper_method = line.pop("paper_method")
        if paper_method not in _PAPER_METHODS:
            raise ValueError(f"{TABLE1_FILE}: unknown paper method {paper_method!r}")
        rows.append(
            PublishedMethodRow(
                method=_PAPER_METHODS[paper_method], paper_method=paper_method, **line
            )
        )
    return tuple(rows)


TABLE1: tuple[PublishedMethodRow, ...] = _read_table1()

#: Table 2 (sampler key -> (joint error, ground truth error)); the paper does not say
#: which character it was measured on
TABLE2: dict[str, tuple[str, str]] = {
    "none": ("0.235", "1.196"),
    "uniform": ("0.057", "0.915"),
    "univariate_gaussian": ("0.049", "0.517"),
    "multivariate_gaussian": ("0.085", "1.366"),
    "gmm": ("0.077", "0.992"),
    "pca_gaussian": ("0.044", "1.482"),
}

#: Table 3 (our rig key -> (paper's row name, training frames, rig DOFs, joint DOFs))
TABLE3: dict[str, tuple[str, str, str, str]] = {
    "quadruped": ("Quadruped", "750", "642", "234"),
    "biped": ("Biped", "750", "697", "144"),
    "face": ("Facial", "300", "49", "18"),
    "squirrel": ("Squirrel", "500", "36", "3375"),
}

#: what §6.1's text adds to Table 3 (used controls; the biped's total differs from Table 3)
TABLE3_NOTE = (
    "§6.1 of the paper: the quadruped has 642 rig DOFs of which 218 are used in the "
    "animation data; the biped 804 of which 204 are used (Table 3 prints 697 for the biped)."
)


def table1_value(rig: str, motion: str, method: str) -> PublishedMethodRow | None:
    """The paper's Table 1 row for ``rig``/``motion``/``method`` (motion matched ignoring case)."""
    wanted = motion.casefold()
    for row in TABLE1:
        if row.character == rig and row.motion.casefold() == wanted and row.method == method:
            return row
    return None


def as_number(printed: str) -> float:
    """A transcribed value as a float (the strings are the exact printed digits)."""
    return float(printed)
