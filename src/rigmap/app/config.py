"""Hydra composition of ``conf/`` as the pipeline apps see it, with the range checks of
:mod:`rigmap.params_checks`: used by the command line and the application layer's verbs
(``rigmap edits``, ``rigmap synth``), so these need not import the CLI (which imports
them)."""

from __future__ import annotations

from pathlib import Path


def find_config_dir(explicit: Path | None = None) -> Path:
    """The Hydra ``conf/`` folder: ``explicit``, else ``./conf``, else the copy inside the
    package (``rigmap/conf``), so an installed rigmap runs from any folder."""
    from rigmap.store.layout import Layout, packaged_conf

    candidates = (
        [Path(explicit)]
        if explicit is not None
        else [Layout.project_conf(Path.cwd()), packaged_conf()]
    )
    for candidate in candidates:
        if (candidate / "config.yaml").is_file():
            return candidate.resolve()
    looked = ", ".join(str(c / "config.yaml") for c in candidates)
    raise FileNotFoundError(
        f"no Hydra config found (looked for {looked}); run from the repository root or pass "
        "--config-dir PATH/TO/conf"
    )


def config_errors() -> tuple[type[Exception], ...]:
    """The errors of a config Hydra or omegaconf cannot compose or resolve (a bad override,
    an unknown group): the user's to fix, so the CLI prints them as one line."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    return (HydraException, OmegaConfBaseException)


def compose_config(
    overrides: list[str],
    config_dir: Path | None = None,
    *,
    with_hydra: bool = False,
    config_name: str = "config",
):
    """``conf/<config_name>.yaml`` with Hydra ``overrides``, as the pipeline apps would see it.

    ``with_hydra`` keeps the ``hydra`` node (its ``runtime.choices`` name the groups chosen).
    """
    from hydra import compose, initialize_config_dir
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from rigmap.config_objects import HYDRA_LOCK

    folder = find_config_dir(config_dir)
    _check_override_syntax(overrides)
    try:
        with HYDRA_LOCK, initialize_config_dir(config_dir=str(folder), version_base="1.3"):
            cfg = compose(
                config_name=config_name, overrides=list(overrides), return_hydra_config=with_hydra
            )
    except (HydraException, OmegaConfBaseException) as error:
        raise ValueError(
            f"config {folder}/{config_name}.yaml with overrides {overrides}: {error}"
        ) from None
    _check_ranges(cfg)
    return cfg


def _check_override_syntax(overrides: list[str]) -> None:
    """Each override parsed alone, so the error names the one Hydra's grammar refuses and says
    to quote it: its lexer message alone ("LexerNoViableAltException") gives no hint that a
    path with spaces or non-ASCII letters must be quoted."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import OverrideParseException

    parser = OverridesParser.create()
    for override in overrides:
        try:
            parser.parse_overrides([override])
        except OverrideParseException:
            key, _, value = override.partition("=")
            quote, shell = ("'", '"') if "'" not in value else ('"', "'")
            hint = f"{key}={quote}{value}{quote}"
            raise ValueError(
                f"override {override!r} is not valid Hydra override syntax; a value with "
                f"spaces, non-ASCII letters or other special characters must be quoted, e.g. "
                f"{hint} (in a shell: {shell}{hint}{shell})"
            ) from None


def _check_ranges(cfg) -> None:
    """The counts, seeds and rates ``rigmap.params_checks`` knows, checked as composed (so a
    bad override is refused naming its key before any work)."""
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    from rigmap.params_checks import FLOAT_RANGES, MIN_COUNTS, range_problems

    values = {}
    for key in (*MIN_COUNTS, *FLOAT_RANGES):
        try:
            values[key] = OmegaConf.select(cfg, key, default=None)
        except OmegaConfBaseException:
            continue  # an interpolation this command does not resolve: not its value
    problems = range_problems(values)
    if problems:
        raise ValueError("; ".join(problems))
