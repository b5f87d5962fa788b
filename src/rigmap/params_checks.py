"""What a value in ``params.yaml`` may be, checked before the file is written.

Stages read values from ``params.yaml`` (``budget.samples=@budget.samples``, filled in by
:mod:`rigmap.app.placeholders`, which checks them here again), so a value
that is the wrong type (``budget.samples=2.5`` or ``abc``), out of range
(``-5``, ``0``), not finite, or carries shell syntax (``;``, ``$(...)``) is
refused here with the key, the value and what was expected, and nothing is written.

Three rules:

- *types*: a value keeps the type it has in the plain composition of
  ``conf/config.yaml`` (an integer stays an integer; a float field takes an
  integer; ``null`` defaults take anything); every float is finite;
- *ranges*: the counts and rates below (the ranges are ours: what the code
  that reads them can work with);
- *shell safety*: no string anywhere holds a shell metacharacter, and no
  string that a stage command interpolates holds whitespace.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

#: key -> (smallest allowed value, what it is); a count of things or passes
MIN_COUNTS: dict[str, tuple[int, str]] = {
    "seed": (0, "a random seed"),
    "budget.samples": (1, "a number of supersamples"),
    "budget.gpr_points": (1, "a number of GPR points"),
    "budget.length_scales": (1, "a number of length scales to try"),
    "budget.cv_splits": (2, "a number of cross-validation splits"),
    "budget.hidden": (1, "a number of hidden units"),
    "budget.epochs": (1, "a number of epochs"),
    "budget.batch_size": (1, "a minibatch size"),
    "budget.refine_iterations": (0, "a number of refinement iterations"),
    "pose.batch_size": (1, "a batch size"),
    "supersample.chunk_size": (1, "a chunk size"),
    "figures.per_row": (1, "a number of figures per row"),
    "rig.corpus.fps": (1, "frames per second"),
    "regressor.hidden": (1, "a number of hidden units"),
    "regressor.epochs": (1, "a number of epochs"),
    "regressor.batch_size": (1, "a minibatch size"),
    "regressor.threads": (1, "a number of threads"),
    "regressor.n_points": (1, "a number of GPR points"),
    "latent.max_script_frames": (1, "the most frames a command script may play"),
}
#: key -> (lower bound, whether the bound itself is allowed, what it is)
FLOAT_RANGES: dict[str, tuple[float, bool, str]] = {
    "regressor.learning_rate": (0.0, False, "a learning rate"),
    "regressor.alpha": (0.0, True, "a regularisation weight"),
    "corpus.variation": (0.0, False, "a variation scale"),
    "sampler.scale": (0.0, False, "a sampling scale"),
    "kernel.length_scale": (0.0, False, "a length scale"),
    "tracking.probe_timeout_s": (0.0, False, "a timeout in seconds"),
}
SHELL_METACHARACTERS = re.compile(r"[;&|$`\\\"'<>(){}*?!#\n\r]")


def param_problems(
    params: Mapping[str, Any], defaults: Mapping[str, Any], interpolated: set[str]
) -> list[str]:
    """One line per bad value of the flattened ``params`` (empty: all good).

    ``defaults``: the flattened plain composition (the types to keep);
    ``interpolated``: keys (or key prefixes) that stage commands paste into a shell.
    """
    problems = []
    for key, value in params.items():
        reached = any(key == k or key.startswith(f"{k}.") for k in interpolated)
        problem = _type_problem(value, defaults.get(key, None)) or _range_problem(key, value)
        problem = problem or _shell_problem(value, reached)
        if problem:
            problems.append(f"{key} = {value!r}: {problem}")
    return problems


def range_problems(values: Mapping[str, Any]) -> list[str]:
    """One line per value of the flattened ``values`` outside its range above (keys not
    listed are not looked at): the check a command runs on its own composed config."""
    problems = []
    for key, value in values.items():
        problem = _range_problem(key, value)
        if problem:
            problems.append(f"{key}={value!r}: {problem}")
    return problems


def _type_problem(value: Any, default: Any) -> str | None:
    for item in value if isinstance(value, list) else [value]:
        if isinstance(item, float) and not math.isfinite(item):
            return "expected a finite number"
    if default is None or isinstance(value, list) or isinstance(default, list):
        return None
    expected = _kind(default)
    if _kind(value) == expected or (expected == "float" and _kind(value) == "int"):
        return None
    return f"expected {_ARTICLE[expected]} (as in conf/), got {_ARTICLE[_kind(value)]}"


_ARTICLE = {
    "bool": "true or false",
    "int": "an integer",
    "float": "a number",
    "str": "a string",
    "null": "null",
    "other": "a mapping",
}


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    for kind in (bool, int, float, str):  # bool before int: True is an int in Python
        if isinstance(value, kind):
            return kind.__name__
    return "other"


def _range_problem(key: str, value: Any) -> str | None:
    if key in MIN_COUNTS and value is not None:
        smallest, what = MIN_COUNTS[key]
        items = value if isinstance(value, list) else [value]  # hidden may be a list of widths
        for item in items:
            if isinstance(item, bool) or not isinstance(item, int) or item < smallest:
                return f"expected an integer >= {smallest} ({what})"
    if key in FLOAT_RANGES and value is not None:
        bound, inclusive, what = FLOAT_RANGES[key]
        number_ok = isinstance(value, int | float) and not isinstance(value, bool)
        if (
            not number_ok
            or not math.isfinite(value)
            or not (value >= bound if inclusive else value > bound)
        ):
            relation = ">=" if inclusive else ">"
            return f"expected a finite number {relation} {bound:g} ({what})"
    return None


def _shell_problem(value: Any, interpolated: bool) -> str | None:
    for item in value if isinstance(value, list) else [value]:
        if not isinstance(item, str):
            continue
        found = SHELL_METACHARACTERS.search(item)
        if found:
            return (
                f"contains {found.group()!r}, a shell metacharacter; DVC pastes params.yaml "
                "values into stage commands, so such values are refused"
            )
        if interpolated and re.search(r"\s", item):
            return "contains whitespace, which would split a stage command's argument"
    return None
