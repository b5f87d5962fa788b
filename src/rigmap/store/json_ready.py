"""Plain JSON from the numbers numpy and pandas hand back."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import Any

import numpy as np


def json_ready(value: Any, *, nonfinite_to_null: bool = True) -> Any:
    """Mappings, lists and numbers as plain JSON: numpy scalars and arrays to Python,
    tuples to lists, paths to strings, and (unless ``nonfinite_to_null=False``)
    non-finite floats to ``None``, since strict JSON has no NaN."""
    strict = nonfinite_to_null
    if isinstance(value, Mapping):
        return {str(k): json_ready(v, nonfinite_to_null=strict) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v, nonfinite_to_null=strict) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist(), nonfinite_to_null=strict)
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if strict and isinstance(value, float) and not math.isfinite(value):
        return None
    return value
