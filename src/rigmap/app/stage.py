"""The one entry point of every pipeline stage: Hydra composes, rigmap's errors read as one line.

A stage script is ``run(cfg)`` plus ``if __name__ == "__main__": run_stage(run)``.
:func:`run_stage` hands ``run`` to ``hydra.main`` (the config is the project's
``conf/config.yaml``, found beside the script's folder) and sorts what goes wrong:

- an error rigmap raises on purpose (:class:`rigmap.errors.RigmapError`), a file the OS
  refuses (any ``OSError`` naming it), ``MemoryError`` and a config Hydra cannot
  compose (``rig=nope``, a bad override) print ``error: <stage>: <message>`` on stderr and
  exit with :data:`USER_ERROR_EXIT` — the user can fix them from the message alone;
- anything else is a bug and keeps its full traceback (exit 1);
- ``RIGMAP_DEBUG=1`` shows the traceback of every error.

A command's ``KEY=@NAME`` and ``KEY=@item.K`` take their values from params.yaml and the
DVC matrix entry (:mod:`~rigmap.app.placeholders`), checked before ``run`` starts.
Before ``run`` sees the config, the chosen rig's ``_overrides_`` are merged over it
(:func:`apply_rig_overrides`: a slow rig's smaller budgets) and dvc.yaml's ``pipeline``
lists are dropped (:func:`stage_config`).

Hydra's own error printing (its trimmed traceback and the ``HYDRA_FULL_ERROR`` hint) is
switched off while the stage runs, so the message above is the only one.
"""

from __future__ import annotations

import inspect
import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rigmap.errors import RigmapError
from rigmap.store.layout import Layout

USER_ERROR_EXIT = 2  # the exit status of an error the user can fix (as argparse's usage errors)
DEBUG_VARIABLE = "RIGMAP_DEBUG"
CONFIG_NAME = "config"
FILE_ERRORS = (FileNotFoundError, PermissionError)  # kept for importers; any OSError counts
PIPELINE_LISTS = "pipeline"  # dvc.yaml's lists of rigs (conf/config.yaml), not a stage's input
RIG_OVERRIDES = "_overrides_"  # config values a rig fixes for every stage (apply_rig_overrides)


def run_stage(
    task: Callable[[Any], Any],
    *,
    name: str | None = None,
    config_dir: str | os.PathLike | None = None,
    config_name: str = CONFIG_NAME,
) -> None:
    """Run ``task(cfg)`` as a Hydra app named ``name`` (default: the script's file name).

    ``config_dir`` defaults to ``<script folder>/../conf`` (``pipelines/`` beside ``conf/``).
    """
    import hydra

    script = Path(inspect.getfile(task)).resolve()
    name = name or script.stem
    config_dir = (
        Path(config_dir) if config_dir is not None else Layout.project_conf(script.parent.parent)
    )

    from rigmap.app.placeholders import apply_params, resolve_argv

    try:  # dvc.yaml's @placeholders: values from params.yaml, never through a shell
        resolved = resolve_argv(sys.argv)
    except Exception as error:
        _exit_if_users(name, error)
        raise
    sys.argv[:] = resolved.argv

    def stage_task(cfg: Any) -> Any:
        # errors inside the task are sorted here: past this point Hydra would print
        # "Error executing job ..." before re-raising
        try:
            return task(stage_config(apply_params(cfg, resolved.params)))
        except Exception as error:
            _exit_if_users(name, error)
            raise

    app = hydra.main(
        config_path=str(config_dir.resolve()), config_name=config_name, version_base="1.3"
    )(stage_task)
    with _hydra_errors_raised():
        try:
            app()
        except Exception as error:  # Hydra could not compose the config (rig=nope, bad override)
            _exit_if_users(name, error)
            raise


def _exit_if_users(name: str, error: Exception) -> None:
    """Print a user error as one message and exit; return for a bug (or when debugging)."""
    from rigmap.tracking.store import tracking_failure

    error = tracking_failure(error) or error  # a stalled tracking server, in one line
    if debugging() or not is_user_error(error):
        return
    sys.stderr.write(f"error: {name}: {error_message(error)}\n")
    sys.stderr.flush()
    raise SystemExit(USER_ERROR_EXIT) from None


def stage_config(cfg: Any) -> Any:
    """The config a stage runs with: the rig's ``_overrides_`` applied, ``pipeline`` dropped.

    ``pipeline`` lists what dvc.yaml runs (rigs per family); no stage reads it, so it stays
    out of what a stage records (``fit.json``'s config), as before the lists existed.
    """
    from omegaconf import DictConfig, open_dict

    cfg = apply_rig_overrides(cfg)
    if isinstance(cfg, DictConfig) and PIPELINE_LISTS in cfg:
        with open_dict(cfg):
            del cfg[PIPELINE_LISTS]
    return cfg


def apply_rig_overrides(cfg: Any) -> Any:
    """``cfg`` with the chosen rig's ``_overrides_`` merged over it (in place), then dropped.

    A rig config may fix values every stage run on it must use, over the experiment and the
    command line: a Blender rig (a slow black box) keeps smaller budgets than the built-in
    rigs whatever ``experiment`` says (``conf/rig/rigify_wolf.yaml``). The key starts with
    ``_`` so ``rigmap.rigs.load`` ignores it where a config is read without this step.
    """
    from omegaconf import DictConfig, open_dict

    rig = cfg.get("rig") if isinstance(cfg, DictConfig) else None
    overrides = rig.get(RIG_OVERRIDES) if rig is not None else None
    if overrides is None:
        return cfg
    with open_dict(cfg):
        cfg.merge_with(overrides)
        del cfg.rig[RIG_OVERRIDES]
    return cfg


def debugging() -> bool:
    """``RIGMAP_DEBUG`` is set to something other than empty, ``0`` or ``false``."""
    return os.environ.get(DEBUG_VARIABLE, "").strip().lower() not in ("", "0", "false", "no")


def is_user_error(error: BaseException) -> bool:
    """An error whose message tells the user what to fix (not a bug in rigmap)."""
    from hydra.errors import HydraException

    if isinstance(error, (RigmapError, HydraException, MemoryError)):
        return True
    # any OSError naming its file: missing, a folder where a file is expected, a full disk
    return isinstance(error, OSError) and bool(error.filename or str(error))


def error_message(error: BaseException) -> str:
    """The error's text; a Hydra composition error also says what caused it."""
    text = str(error).strip()
    cause = error.__cause__
    if cause is not None and str(cause).strip() and str(cause).strip() not in text:
        text = f"{text}\n{str(cause).strip()}"
    if isinstance(error, KeyError) and len(error.args) == 1 and isinstance(error.args[0], str):
        text = error.args[0]  # KeyError's str() quotes its message
    return text or type(error).__name__


@contextmanager
def _hydra_errors_raised() -> Iterator[None]:
    """Make Hydra re-raise the task's exceptions (instead of printing and exiting 1)."""
    previous = os.environ.get("HYDRA_FULL_ERROR")
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = previous
