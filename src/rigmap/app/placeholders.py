"""Stage commands name their values, never paste them: ``seed=@seed``, ``rig=@item.rig``.

DVC runs a stage's ``cmd`` through a shell. A value interpolated into it with ``${...}``
comes from ``params.yaml``, which ``dvc exp run -S`` or a hand edit can set to anything,
and is shell syntax before any check of ours runs (``seed: "0; touch X"``), whatever
stage ran first (``dvc repro --single-item`` skips the ``check_params`` stage). So every
command in dvc.yaml is a fixed string: ``KEY=@NAME`` asks the stage for params.yaml's
``NAME``, ``KEY=@item.K`` for the matrix entry DVC is running (its ``DVC_STAGE``, such
as ``fit_gpr@biped-linear``). :func:`resolve_argv` fills them in before Hydra composes,
never through a shell, and :func:`apply_params` checks each value
(:mod:`rigmap.params_checks`: type as in conf/, range) before the stage sees it.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError
from rigmap.store.pipeline_files import PipelineFileError, short_name, stage_families

PLACEHOLDER = "@"
ITEM = "item."
STAGE_VARIABLE = "DVC_STAGE"  # DVC sets it to the stage's address for every command it runs
#: a matrix entry's value: a name (of a rig, sampler, kernel or split), nothing a parser
#: could read as syntax (ours)
SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.:+-]*")
_KEY = re.compile(r"[A-Za-z_][\w.]*")


class PlaceholderError(RigmapError, ValueError):
    """A ``@name`` in a stage command that cannot be filled, or a value that may not fill it."""


@dataclass
class Resolved:
    """The command line with matrix entries filled in, and params.yaml values to merge."""

    argv: list[str]
    params: dict[str, tuple[str, Any]] = field(default_factory=dict)  # KEY -> (NAME, value)


def resolve_argv(
    argv: Sequence[str], project: Path | None = None, stage: str | None = None
) -> Resolved:
    """``argv`` with every ``KEY=@item.K`` replaced; ``KEY=@NAME`` set aside with its value.

    ``project``: the folder of dvc.yaml and params.yaml (default: cwd, where DVC runs);
    ``stage``: the DVC address (default: ``$DVC_STAGE``).
    """
    import os

    project = Path.cwd() if project is None else Path(project)
    stage = os.environ.get(STAGE_VARIABLE) if stage is None else stage
    resolved = Resolved([argv[0]] if argv else [])
    params: dict[str, Any] | None = None
    for arg in argv[1:]:
        key, sep, value = arg.partition("=")
        if not sep or not value.startswith(PLACEHOLDER) or not _KEY.fullmatch(value[1:]):
            resolved.argv.append(arg)
            continue
        name = value[1:]
        if params is None:
            params = _read_params(project)
        if name.startswith(ITEM):
            item = _matrix_item(project, stage, params)
            resolved.argv.append(f"{key}={_item_value(item, name[len(ITEM) :], arg)}")
        else:
            resolved.params[key.lstrip("+")] = (name, _lookup(params, name, arg))
    return resolved


def apply_params(cfg: Any, params: Mapping[str, tuple[str, Any]]) -> Any:
    """Merge the params.yaml values over the composed ``cfg``, each checked first.

    Merged as a command-line override would be (before a rig's ``_overrides_``); a value
    of the wrong type (as in conf/) or out of range raises ``PlaceholderError``.
    """
    from omegaconf import OmegaConf, open_dict

    from rigmap.params_checks import param_problems

    problems = []
    for key, (name, value) in params.items():
        default = OmegaConf.select(cfg, key, default=None, throw_on_missing=False)
        problems += param_problems({name: value}, {name: default}, {name})
    if problems:
        raise PlaceholderError(
            f"params.yaml: {len(problems)} bad value(s), the stage did not run: "
            + "; ".join(problems)
        )
    with open_dict(cfg):
        for key, (_, value) in params.items():
            OmegaConf.update(cfg, key, value, merge=False)
    return cfg


def _read_params(project: Path) -> dict[str, Any]:
    import yaml

    path = project / "params.yaml"
    try:
        params = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError) as error:
        raise PlaceholderError(f"{path}: not readable as YAML ({error})") from None
    if not isinstance(params, dict):
        raise PlaceholderError(f"{path}: expected a mapping of parameters")
    return params


def _lookup(tree: Mapping[str, Any], dotted: str, arg: str) -> Any:
    node: Any = tree
    for part in dotted.split("."):
        if not isinstance(node, Mapping) or part not in node:
            raise PlaceholderError(f"{arg}: params.yaml has no {dotted!r}")
        node = node[part]
    return node


def _item_value(item: Mapping[str, Any], key: str, arg: str) -> str:
    if key not in item:
        raise PlaceholderError(f"{arg}: the matrix entry has no {key!r} (it has {sorted(item)})")
    value = item[key]
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)  # a matrix of seeds (pipeline.spread_seeds): digits, nothing to quote
    if not isinstance(value, str) or not SAFE_NAME.fullmatch(value):
        raise PlaceholderError(
            f"{arg}: matrix value {value!r} is not a plain name or an integer (letters, "
            "digits, _ . : + -)"
        )
    return value


def _matrix_item(project: Path, stage: str | None, params: Mapping[str, Any]) -> dict[str, Any]:
    """The matrix entry DVC runs as ``stage`` (``name@key``), found as DVC names them."""
    if not stage or "@" not in stage:
        raise PlaceholderError(
            f"@item placeholders are filled from the DVC matrix entry being run, but "
            f"${STAGE_VARIABLE} is {stage!r}; run it with dvc repro, or give the value itself"
        )
    name, _, wanted = short_name(stage).partition("@")  # DVC may give path/dvc.yaml:name@key
    try:
        matrix = stage_families(project)[name].body["matrix"]
    except (PipelineFileError, KeyError, TypeError) as error:
        raise PlaceholderError(
            f"{project}: no matrix stage {name!r} in the pipeline's stage files ({error})"
        ) from None
    lists = {key: _matrix_list(values, params, name) for key, values in matrix.items()}
    for combination in itertools.product(*lists.values()):
        if "-".join(_fragment(value) for value in combination) == wanted:
            return dict(zip(lists, combination, strict=True))
    raise PlaceholderError(f"dvc.yaml: stage {name!r} has no matrix entry {wanted!r}")


def _matrix_list(values: Any, params: Mapping[str, Any], stage: str) -> list[Any]:
    if isinstance(values, str):
        found = re.fullmatch(r"\$\{\s*([A-Za-z_][\w.]*)\s*\}", values)
        if found is None:
            raise PlaceholderError(f"dvc.yaml: stage {stage!r}: matrix value {values!r}")
        values = _lookup(params, found.group(1), f"{stage}.matrix")
    if not isinstance(values, list):
        raise PlaceholderError(f"dvc.yaml: stage {stage!r}: a matrix entry is not a list")
    return values


def _fragment(value: Any) -> str:
    """How DVC spells a matrix value in a stage's name (dvc.parsing's ``to_str``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)
