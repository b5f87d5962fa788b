"""``params.yaml``: the experiment the DVC pipeline runs, composed from ``conf/`` by Hydra.

DVC's Hydra integration (``hydra.enabled`` in ``.dvc/config``) makes
``dvc exp run -S experiment=paper -S regressor.hidden=1024`` compose
``conf/config.yaml`` with those overrides, resolve every interpolation and dump
the result to ``params.yaml`` before reproducing. The stages in ``dvc.yaml``
list the values they use from it (``params:``) and name them in their command lines
(``python pipelines/supersample.py ... budget.samples=@budget.samples``; the stage reads
the value itself, so no value ever passes through a shell), so
DVC re-runs exactly the stages whose values changed, ``dvc.lock`` records the
values each output was made with, and ``dvc exp show`` lists them.

``rigmap reproduce`` writes ``params.yaml`` the same way (``compose_params``
gives the same text DVC writes) and then runs ``dvc repro``.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError
from rigmap.params_checks import param_problems
from rigmap.store import write_text_atomic
from rigmap.store.layout import CONFIG_NAME, PARAMS_STAMP, Layout, find_project_root
from rigmap.store.pipeline_files import ROOT_FILE, pipeline_text

PARAMS_FILE = "params.yaml"
EXPERIMENT_GROUP = "experiment"


class ParamsError(RigmapError, ValueError):
    """Overrides or a project layout from which no ``params.yaml`` can be composed."""


@dataclass(frozen=True)
class ParamsUpdate:
    """A ``params.yaml`` written (or left as it was) and what differs from the defaults."""

    path: Path
    changed: bool
    params: dict[str, Any]
    differs_from_defaults: tuple[str, ...]


def project_root(start: str | Path | None = None) -> Path:
    """The project at or above ``start`` (default: cwd), or an error saying none is there."""
    root = find_project_root(start)
    if root is None:
        start = (Path.cwd() if start is None else Path(start)).resolve()
        raise ParamsError(
            f"no project found: expected dvc.yaml and conf/{CONFIG_NAME}.yaml in {start} or a "
            "folder above it; run from the rigmap repository or pass --project DIR"
        )
    return root


def experiment_names(config_dir: str | Path) -> list[str]:
    """The choices of the ``experiment`` group (``conf/experiment/*.yaml``)."""
    return sorted(p.stem for p in (Path(config_dir) / EXPERIMENT_GROUP).glob("*.yaml"))


def check_overrides(overrides: Sequence[str], config_dir: str | Path) -> list[str]:
    """Hydra ``key=value`` overrides; a clear error for anything else or an unknown experiment."""
    checked = []
    for override in overrides:
        key, sep, value = str(override).partition("=")
        if not sep or not key.lstrip("+~"):
            raise ParamsError(
                f"override {override!r}: expected KEY=VALUE (e.g. experiment=paper, "
                "budget.samples=20000)"
            )
        if key == EXPERIMENT_GROUP:
            choices = experiment_names(config_dir)
            if value not in choices:
                raise ParamsError(
                    f"override {override!r}: unknown experiment {value!r}; expected one of "
                    f"{choices} (conf/{EXPERIMENT_GROUP}/*.yaml)"
                )
        checked.append(str(override))
    return checked


def compose_params(config_dir: str | Path, overrides: Sequence[str] = ()) -> str:
    """The text of ``params.yaml``: the config composed with ``overrides`` and fully resolved.

    The same text DVC's Hydra integration writes (``OmegaConf.to_yaml`` of the resolved
    config), so ``rigmap reproduce`` and ``dvc exp run -S`` agree byte for byte.
    """
    from hydra import compose, initialize_config_dir
    from hydra.errors import HydraException
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    from rigmap.config_objects import HYDRA_LOCK

    config_dir = Path(config_dir).resolve()
    overrides = check_overrides(overrides, config_dir)
    try:
        with HYDRA_LOCK, initialize_config_dir(config_dir=str(config_dir), version_base=None):
            cfg = compose(config_name=CONFIG_NAME, overrides=list(overrides))
        OmegaConf.resolve(cfg)
    except (HydraException, OmegaConfBaseException) as error:
        raise ParamsError(
            f"cannot compose {config_dir}/{CONFIG_NAME}.yaml with overrides {list(overrides)}: "
            f"{error}"
        ) from None
    return OmegaConf.to_yaml(cfg)


def write_params(
    project: str | Path, overrides: Sequence[str] = (), *, defaults: bool = True
) -> ParamsUpdate:
    """Compose ``<project>/params.yaml`` from ``<project>/conf`` and ``overrides``, atomically.

    Every value is checked first (:mod:`rigmap.params_checks`: types, ranges, shell
    safety); a bad one raises ``ParamsError`` naming the key, and nothing is written.
    The file is rewritten only when its text changes (so ``dvc repro`` sees no change
    when the experiment is the same). With ``defaults``, also report which values differ
    from the plain composition (no overrides).
    """
    import yaml

    project = Path(project)
    config_dir = Layout.project_conf(project)
    text = compose_params(config_dir, overrides)
    params = yaml.safe_load(text)
    flat, flat_plain = flatten(params), flatten(yaml.safe_load(compose_params(config_dir, ())))
    check_params(flat, flat_plain, project / "dvc.yaml", overrides)
    path = project / PARAMS_FILE
    changed = not path.is_file() or path.read_text(encoding="utf-8") != text
    if changed:
        write_text_atomic(path, text)
    differing: tuple[str, ...] = ()
    if defaults:
        differing = tuple(
            key
            for key in sorted(set(flat) | set(flat_plain))
            if flat.get(key, _ABSENT) != flat_plain.get(key, _ABSENT)
        )
    return ParamsUpdate(path, changed, params, differing)


_ABSENT = object()


def check_params(
    flat: Mapping[str, Any],
    flat_plain: Mapping[str, Any],
    dvc_yaml: Path,
    overrides: Sequence[str] = (),
    *,
    verdict: str = "params.yaml not written",
) -> None:
    """Refuse (``ParamsError``, one line per bad key) values that may not reach params.yaml."""
    interpolated = interpolated_params(dvc_yaml) if dvc_yaml.is_file() else set()
    problems = param_problems(flat, flat_plain, interpolated)
    if problems:
        given = f" (overrides {list(overrides)})" if overrides else ""
        raise ParamsError(
            f"{verdict}{given}: {len(problems)} bad value(s):\n  " + "\n  ".join(problems)
        )


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}`` (lists stay values)."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            flat.update(flatten(value, f"{name}."))
        else:
            flat[name] = value
    return flat


_INTERPOLATION = re.compile(r"\$\{\s*([A-Za-z_][\w.]*)\s*\}")
_PLACEHOLDER = re.compile(r"=@([A-Za-z_][\w.]*)")  # a stage command's KEY=@NAME


def interpolated_params(dvc_yaml: str | Path) -> set[str]:
    """The ``params.yaml`` keys that the stages read: ``${pipeline.rigs}`` or ``seed=@seed``,
    in ``dvc_yaml`` and the stage files beside it (:mod:`rigmap.store.pipeline_files`).

    Commands name their values (``@seed``, filled in by :mod:`rigmap.app.placeholders`,
    never by a shell); ``${...}`` is left for matrix lists and paths.
    """
    dvc_yaml = Path(dvc_yaml)
    if dvc_yaml.name == ROOT_FILE:
        text = pipeline_text(dvc_yaml.parent)
    else:
        text = dvc_yaml.read_text(encoding="utf-8")
    keys = set(_INTERPOLATION.findall(text)) | set(_PLACEHOLDER.findall(text))
    return {k for k in keys if not k.startswith("item.") and k != "item"}


def reaching_stages(keys: Sequence[str], dvc_yaml: str | Path) -> list[str]:
    """Which of ``keys`` some stage reads, directly or through a node it interpolates."""
    read = interpolated_params(dvc_yaml)
    return [k for k in keys if any(k == r or k.startswith(f"{r}.") for r in read)]


CHECKED_STAMP = PARAMS_STAMP  # the check_params stage's output (Layout.params_stamp)


def check_params_file(project: str | Path, params_file: str | Path = PARAMS_FILE) -> None:
    """The ``check_params`` DVC stage: refuse a ``params.yaml`` however it was written.

    ``rigmap reproduce`` checks values before it writes them; ``dvc exp run -S`` and a
    hand-edited file do not pass through it. Every stage depends on this stage's stamp,
    so DVC runs it first and stops at a bad value before any command interpolates it.
    The stamp's text never changes, so a passing check re-runs nothing downstream.
    """
    import yaml

    project = Path(project)
    path = project / params_file
    try:
        params = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as error:
        raise ParamsError(f"{path}: not readable as YAML ({error})") from None
    plain = yaml.safe_load(compose_params(Layout.project_conf(project), ()))
    verdict = f"{path} refused before any stage ran"
    check_params(flatten(params), flatten(plain), project / "dvc.yaml", verdict=verdict)
    write_text_atomic(Layout.of_project(project).params_stamp(), "params.yaml checked\n")


def stale_params(project: str | Path, params_file: str | Path = PARAMS_FILE) -> list[str]:
    """The keys where the committed ``params.yaml`` differs from what ``conf/`` composes.

    A stale file makes a plain ``dvc repro`` on a fresh clone run other settings than
    the ones the report states; CI runs this before reproducing (``.ci/run``).
    """
    import yaml

    project = Path(project)
    path = project / params_file
    composed = compose_params(Layout.project_conf(project), ())
    try:
        text = path.read_text(encoding="utf-8")
        flat = flatten(yaml.safe_load(text) or {})
    except (OSError, yaml.YAMLError) as error:
        raise ParamsError(f"{path}: not readable as YAML ({error})") from None
    if text == composed:
        return []
    plain = flatten(yaml.safe_load(composed))
    keys = sorted(set(flat) | set(plain))
    return [k for k in keys if flat.get(k, _ABSENT) != plain.get(k, _ABSENT)] or ["(layout)"]


_USAGE = "usage: python -m rigmap.pipeline_params {check [params.yaml] | fresh}"


def main(argv: Sequence[str] | None = None) -> int:
    """``check [params.yaml]`` (the check_params stage); ``fresh`` (params.yaml is conf/'s)."""
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    if args == ["fresh"]:
        try:
            stale = stale_params(Path.cwd())
        except ParamsError as error:
            print(f"error: params.yaml: {error}", file=sys.stderr)
            return 2
        if stale:
            print(
                f"error: params.yaml: differs from what conf/ composes at {', '.join(stale)}; "
                "regenerate it with `rigmap reproduce --params-only` and commit it",
                file=sys.stderr,
            )
            return 2
        return 0
    if not args or args[0] != "check" or len(args) > 2:
        print(_USAGE, file=sys.stderr)
        return 2
    try:
        check_params_file(Path.cwd(), args[1] if len(args) == 2 else PARAMS_FILE)
    except ParamsError as error:
        print(f"error: check_params: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
