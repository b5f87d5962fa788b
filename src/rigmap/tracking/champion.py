"""The ``champion`` alias of a registered mapping: the version with the lowest test error.

Each registered version of ``rigmap-<rig>-<regressor>`` carries its score as a version tag
(``joint_error``, lower is better); the alias moves to a new version only when it beats the
current champion, so ``models:/rigmap-<rig>-<regressor>@champion`` always loads the best
mapping logged so far, whatever order sweeps and pipeline runs finish in.
"""

from __future__ import annotations

import math

from mlflow import MlflowClient
from mlflow.exceptions import MlflowException

from rigmap.tracking.pyfunc_model import registered_model_name

CHAMPION = "champion"
CHAMPION_METRIC = "joint_error"  # mean squared joint distance on the test clips (lower is better)


def champion_uri(rig: str, regressor: str) -> str:
    """``models:/rigmap-<rig>-<regressor>@champion``: load it with
    ``rigmap.tracking.load_pyfunc_model``."""
    return f"models:/{registered_model_name(rig, regressor)}@{CHAMPION}"


def promote_if_better(
    client: MlflowClient, name: str, version: str, score: float, *, metric: str = CHAMPION_METRIC
) -> bool:
    """Tag ``version`` with its score; point ``champion`` at it if it beats the current one."""
    score = float(score)
    if not math.isfinite(score):
        raise ValueError(f"champion: {name} version {version} has a non-finite {metric} {score}")
    client.set_model_version_tag(name, str(version), metric, repr(score))
    try:
        current = client.get_model_version_by_alias(name, CHAMPION)
    except MlflowException:  # no champion yet
        current = None
    if current is not None and str(current.version) != str(version):
        best = current.tags.get(metric)
        if best is not None and float(best) <= score:
            return False
    client.set_registered_model_alias(name, CHAMPION, str(version))
    return True
