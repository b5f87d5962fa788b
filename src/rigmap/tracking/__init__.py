"""MLflow tracking for rigmap: the one package that talks to MLflow.

``Tracker.open()`` resolves and checks the store (local SQLite by default),
``start_parent_run`` opens a sweep's run in the rig's experiment,
``log_method_run`` adds one method's child run, and ``log_inverse_mapping``
stores a fitted mapping as a pyfunc model registered as ``rigmap-<rig>-<regressor>``;
``load_pyfunc_model`` loads one after checking it holds no code.
"""

from rigmap.tracking.champion import CHAMPION, champion_uri, promote_if_better
from rigmap.tracking.keys import TrackingKeyError, flatten_config, method_metrics, safe_name
from rigmap.tracking.pyfunc_model import (
    InverseMappingModel,
    LoggedMapping,
    MappingLoggingError,
    UntrustedModelError,
    allow_mapping_class,
    allowed_mapping_classes,
    joint_columns,
    load_pyfunc_model,
    log_inverse_mapping,
    registered_model_name,
)
from rigmap.tracking.runs import (
    MappingToLog,
    MethodRun,
    ParentRun,
    Tracker,
    experiment_name,
    log_method_run,
    start_parent_run,
)
from rigmap.tracking.store import (
    TrackingUnavailableError,
    check_reachable,
    default_tracking_uri,
    resolve_tracking_uri,
)

__all__ = [
    "CHAMPION",
    "InverseMappingModel",
    "LoggedMapping",
    "MappingLoggingError",
    "MappingToLog",
    "MethodRun",
    "ParentRun",
    "Tracker",
    "TrackingKeyError",
    "TrackingUnavailableError",
    "UntrustedModelError",
    "allow_mapping_class",
    "allowed_mapping_classes",
    "champion_uri",
    "check_reachable",
    "default_tracking_uri",
    "experiment_name",
    "flatten_config",
    "joint_columns",
    "load_pyfunc_model",
    "log_inverse_mapping",
    "log_method_run",
    "method_metrics",
    "promote_if_better",
    "registered_model_name",
    "resolve_tracking_uri",
    "safe_name",
    "start_parent_run",
]
