"""The paper's published numbers (Holden, Saito, Komura 2017, Tables 1-3), transcribed.

They were measured on the authors' Maya characters — other rigs, other
animation, other length units, a 2017 laptop — so they sit beside ours for
orientation only, never as a target. Values are kept as the strings the paper
prints (``"0.56"``, ``"9.3"``, ``"0.240"``) so nothing is rounded or padded in
transcription; ``as_number`` converts one when a figure needs it.
"""

from __future__ import annotations

from dataclasses import dataclass

SOURCE = "Holden, Saito & Komura 2017"
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

# Table 1: character/motion, method, joint error, ground truth error, total time (s), fps
_TABLE1 = """
quadruped|Jumping & Playing|Maya Script|3.566|1.406|2.79|25.04
quadruped|Jumping & Playing|GPR|0.153|3.877|0.21|315.06
quadruped|Jumping & Playing|GPR & Learned Jacobian|0.147|3.877|10.73|6.42
quadruped|Jumping & Playing|GPR & Computed Jacobian|0.071|3.864|41.24|1.67
quadruped|Jumping & Playing|NN|0.087|2.604|0.21|319.44
quadruped|Jumping & Playing|NN & Computed Jacobian|0.050|2.597|40.63|1.69
quadruped|Begging Excitedly|Maya Script|0.161|0.424|2.68|30.95
quadruped|Begging Excitedly|GPR|0.022|0.565|0.24|340.24
quadruped|Begging Excitedly|GPR & Learned Jacobian|0.020|0.566|11.51|7.12
quadruped|Begging Excitedly|GPR & Computed Jacobian|0.007|0.56|32.75|2.50
quadruped|Begging Excitedly|NN|0.011|1.005|0.28|283.73
quadruped|Begging Excitedly|NN & Computed Jacobian|0.005|1.002|33.02|2.48
quadruped|Turning & Galloping|Maya Script|1.023|0.972|1.27|29.13
quadruped|Turning & Galloping|GPR|0.041|1.547|0.18|195.65
quadruped|Turning & Galloping|GPR & Learned Jacobian|0.039|1.547|6.29|5.71
quadruped|Turning & Galloping|GPR & Computed Jacobian|0.023|1.537|23.86|1.50
quadruped|Turning & Galloping|NN|0.036|0.839|0.17|208.09
quadruped|Turning & Galloping|NN & Computed Jacobian|0.020|0.836|24.29|1.48
quadruped|Average|Maya Script|1.583|0.934|2.24|28.38
quadruped|Average|GPR|0.072|1.996|0.21|283.65
quadruped|Average|GPR & Learned Jacobian|0.068|2.000|9.51|6.41
quadruped|Average|GPR & Computed Jacobian|0.033|1.987|32.61|1.89
quadruped|Average|NN|0.044|1.482|0.22|270.42
quadruped|Average|NN & Computed Jacobian|0.025|1.478|32.64|1.88
biped|Range of Motion|Maya Script|10.833|3.143|9.40|14.46
biped|Range of Motion|GPR|0.460|0.214|0.22|608.10
biped|Range of Motion|GPR & Learned Jacobian|0.326|0.215|22.75|5.93
biped|Range of Motion|GPR & Computed Jacobian|0.121|0.206|53.74|2.51
biped|Range of Motion|NN|0.339|0.157|0.25|527.34
biped|Range of Motion|NN & Computed Jacobian|0.052|0.151|60.58|2.22
biped|Swing Dance|Maya Script|8.871|2.852|4.56|14.23
biped|Swing Dance|GPR|0.133|0.051|0.15|426.66
biped|Swing Dance|GPR & Learned Jacobian|0.089|0.051|11.56|5.53
biped|Swing Dance|GPR & Computed Jacobian|0.037|0.048|24.45|2.61
biped|Swing Dance|NN|0.198|0.076|0.17|357.54
biped|Swing Dance|NN & Computed Jacobian|0.044|0.073|29.18|2.19
biped|Tai chi|Maya Script|8.198|3.091|13.94|14.33
biped|Tai chi|GPR|0.361|0.233|0.30|656.76
biped|Tai chi|GPR & Learned Jacobian|0.282|0.233|37.26|5.34
biped|Tai chi|GPR & Computed Jacobian|0.083|0.227|85.71|2.32
biped|Tai chi|NN|0.183|0.125|0.30|646.10
biped|Tai chi|NN & Computed Jacobian|0.031|0.122|89.88|2.21
biped|Average|Maya Script|9.300|3.028|9.3|14.34
biped|Average|GPR|0.318|0.166|0.22|563.80
biped|Average|GPR & Learned Jacobian|0.232|0.166|23.85|5.6
biped|Average|GPR & Computed Jacobian|0.080|0.160|54.63|2.48
biped|Average|NN|0.240|0.119|0.240|510.32
biped|Average|NN & Computed Jacobian|0.042|0.115|59.88|2.20
"""


def _parse_table1() -> tuple[PublishedMethodRow, ...]:
    rows = []
    for line in _TABLE1.strip().splitlines():
        character, motion, paper_method, *numbers = line.split("|")
        rows.append(
            PublishedMethodRow(
                character, motion, _PAPER_METHODS[paper_method], paper_method, *numbers
            )
        )
    return tuple(rows)


TABLE1: tuple[PublishedMethodRow, ...] = _parse_table1()

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
