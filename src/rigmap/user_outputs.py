"""Where a user's own runs write: ``outputs/`` (git-ignored), never the tracked folders.

``rigmap learn``, ``edits``, ``synth``, ``map``, ``fit`` and ``evaluate`` are a user's own
runs, not the reproduced experiment: written into ``data/``, ``models/`` or ``metrics/``
they would show up in ``git status`` and change the inputs DVC hashes (``models/<rig>``
is an evaluate stage's dependency). So the ``paths.*`` they write default to
``outputs/<key>`` (``/outputs/`` is in .gitignore); the pipeline's data they only read stays
where it is; a ``paths.<key>=DIR`` override names the user's own folder.
The DVC stages (``pipelines/*.py``) keep ``conf/config.yaml``'s paths.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rigmap.store.layout import ROOTS, USER_OUTPUTS

PATH_KEYS = ROOTS


def user_paths(
    overrides: Sequence[str], keys: Sequence[str] = PATH_KEYS, root: Path = USER_OUTPUTS
) -> list[str]:
    """Hydra overrides putting ``paths.<key>`` under ``root``, for each key not overridden."""
    given = {str(o).partition("=")[0].lstrip("+~") for o in overrides}
    return [f"paths.{key}={Path(root) / key}" for key in keys if f"paths.{key}" not in given]
