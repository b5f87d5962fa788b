"""The shell arguments every verb that composes conf/ shares: its Hydra overrides and the
conf/ folder, worded once so ``--help`` says the same thing everywhere."""

from __future__ import annotations

from pathlib import Path

CONFIG_DIR_HELP = "the Hydra conf/ folder (default: ./conf, else the copy inside the package)"


def config_dir_option(command) -> None:
    """``--config-dir``: the conf/ folder (see :func:`rigmap.app.config.find_config_dir`)."""
    command.add_argument("--config-dir", type=Path, default=None, help=CONFIG_DIR_HELP)


def override_arguments(command, config_name: str, examples: str) -> None:
    """``KEY=VALUE ...`` Hydra overrides of ``conf/<config_name>.yaml`` and ``--config-dir``."""
    command.add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help=f"Hydra overrides of conf/{config_name}.yaml ({examples})",
    )
    config_dir_option(command)
