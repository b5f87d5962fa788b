"""How a pipeline stage runs: :mod:`~rigmap.stage.runner` (Hydra, errors as one message) and
:mod:`~rigmap.stage.inputs` (the plain objects a stage builds from its config)."""

from rigmap.stage.runner import (
    RIG_OVERRIDES,
    USER_ERROR_EXIT,
    apply_rig_overrides,
    debugging,
    error_message,
    is_user_error,
    run_stage,
    stage_config,
)

__all__ = [
    "RIG_OVERRIDES",
    "USER_ERROR_EXIT",
    "apply_rig_overrides",
    "debugging",
    "error_message",
    "is_user_error",
    "run_stage",
    "stage_config",
]
