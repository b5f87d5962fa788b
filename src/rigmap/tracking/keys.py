"""Names and values MLflow accepts: metric keys, flattened config params, tags.

MLflow (3.x, POSIX) allows metric and param names made of letters, digits,
``_ - . / : `` and spaces, at most 250 characters, and rejects names that are
not normalised paths (``a//b``, ``./a``, a trailing ``/``). Param values are
cut at 6000 characters and tag values at 8000 — silently, with a warning.

rigmap keys are ``<metric>`` for the average over all test frames and
``<metric>/<clip>`` per clip. Clip names come from people ("jump & play"), so
they are reduced to ``[A-Za-z0-9_.-]`` (colons and spaces are legal on POSIX
but not on Windows, and make keys awkward to type). Long param values are
truncated here, with a marker that says how much was cut, rather than by MLflow.
"""

from __future__ import annotations

import json
import posixpath
import re
from collections.abc import Mapping, Sequence
from typing import Any

from rigmap.errors import RigmapError

MAX_KEY_LENGTH = 250
MAX_PARAM_VALUE_LENGTH = 6000
MAX_TAG_VALUE_LENGTH = 8000

_UNSAFE = re.compile(r"[^A-Za-z0-9_.\-]+")
_KEY_ALLOWED = re.compile(r"^[A-Za-z0-9_.\-/]+$")


class TrackingKeyError(RigmapError, ValueError):
    """A name that cannot become an MLflow key, or two names that become the same key."""


def safe_name(name: str) -> str:
    """``name`` reduced to ``[A-Za-z0-9_.-]``: each run of other characters becomes ``_``."""
    cleaned = _UNSAFE.sub("_", str(name)).strip("_")
    if not cleaned.strip("."):  # empty, ".", "..": not a usable path component
        raise TrackingKeyError(
            f"name {name!r} has no letters or digits left after reducing it to "
            "[A-Za-z0-9_.-]; rename it"
        )
    return cleaned


def safe_names(names: list[str] | tuple[str, ...], what: str) -> dict[str, str]:
    """Map each name to ``safe_name(name)``; refuse two names that become the same key."""
    mapping: dict[str, str] = {}
    seen: dict[str, str] = {}
    for name in names:
        key = safe_name(name)
        if key in seen and seen[key] != name:
            raise TrackingKeyError(
                f"{what} {seen[key]!r} and {name!r} both become {key!r} in MLflow keys; "
                "rename one of them"
            )
        seen[key] = name
        mapping[name] = key
    return mapping


def method_metrics(summary: Mapping[str, Any]) -> dict[str, float]:
    """MLflow metrics from a metrics JSON (``MethodResult.to_dict()``).

    ``average`` becomes ``<metric>``; ``clips[<clip>]`` becomes ``<metric>/<safe clip>``.
    """
    try:
        average, clips = summary["average"], summary["clips"]
    except (KeyError, TypeError):
        keys = sorted(summary) if isinstance(summary, Mapping) else type(summary).__name__
        raise TrackingKeyError(
            f"metrics summary: expected a mapping with 'average' and 'clips' (the metrics "
            f"JSON of a MethodResult), got keys {keys}"
        ) from None
    metrics = {_check_key(str(k)): _number(v, f"average.{k}") for k, v in average.items()}
    clip_keys = safe_names(list(clips), "clips")
    for clip, values in clips.items():
        for metric, value in values.items():
            key = _check_key(f"{metric}/{clip_keys[clip]}")
            metrics[key] = _number(value, f"clips[{clip!r}].{metric}")
    return metrics


def flatten_config(config: Any, sep: str = ".") -> dict[str, str]:
    """A (Hydra) config as flat MLflow params: ``{"regressor.kernel.name": "multiquadric"}``.

    Non-string values are written as JSON (``true``, ``null``, ``[1, 2]``);
    values longer than MLflow's limit are truncated with a marker.
    """
    flat: dict[str, str] = {}
    _flatten(plain_container(config), "", sep, flat)
    return flat


def truncate(value: str, limit: int) -> str:
    """``value`` cut to at most ``limit`` characters, ending in a marker if it was cut."""
    if len(value) <= limit:
        return value
    keep = limit
    while True:  # the marker's length depends on the count it reports: settle both
        marker = f"...[truncated {len(value) - keep} of {len(value)} chars]"
        if keep + len(marker) <= limit:
            return value[:keep] + marker
        keep = limit - len(marker)


def _flatten(node: Any, prefix: str, sep: str, out: dict[str, str]) -> None:
    if isinstance(node, Mapping) and node:
        for key, value in node.items():
            _flatten(value, f"{prefix}{sep}{key}" if prefix else str(key), sep, out)
        return
    if not prefix:
        return
    key = _check_key(_UNSAFE.sub("_", prefix) if not _KEY_ALLOWED.match(prefix) else prefix)
    if key in out:
        raise TrackingKeyError(f"config keys collide as MLflow param {key!r} (from {prefix!r})")
    text = node if isinstance(node, str) else json.dumps(node, default=str)
    out[key] = truncate(text, MAX_PARAM_VALUE_LENGTH)


def plain_container(config: Any) -> Any:
    """Nested mappings and sequences as plain dicts and lists (a config node reads as one), so
    the YAML and JSON writers take it; anything else as given."""
    if isinstance(config, Mapping):
        return {key: plain_container(value) for key, value in config.items()}
    if isinstance(config, Sequence) and not isinstance(config, str | bytes):
        return [plain_container(value) for value in config]
    return config


def _check_key(key: str) -> str:
    if len(key) > MAX_KEY_LENGTH:
        raise TrackingKeyError(
            f"MLflow key {key[:60]!r}... is {len(key)} characters; at most {MAX_KEY_LENGTH}"
        )
    if not _KEY_ALLOWED.match(key) or posixpath.normpath(key) != key or key.startswith("/"):
        raise TrackingKeyError(
            f"MLflow key {key!r}: expected letters, digits, '_', '-', '.' and single '/' "
            "between parts"
        )
    return key


def _number(value: Any, where: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise TrackingKeyError(f"metric {where}: expected a number, got {value!r}") from None
    if number != number or number in (float("inf"), float("-inf")):
        raise TrackingKeyError(f"metric {where}: expected a finite number, got {value!r}")
    return number
