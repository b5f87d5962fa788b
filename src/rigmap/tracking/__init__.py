"""MLflow tracking for rigmap: the one package that talks to MLflow.

``Tracker.open()`` resolves and checks the store (local SQLite by default),
``start_parent_run`` opens a sweep's run in the rig's experiment,
``log_method_run`` adds one method's child run, and ``log_inverse_mapping``
stores a fitted mapping as a pyfunc model registered as ``rigmap-<rig>-<regressor>``;
``load_pyfunc_model`` loads one after checking it holds no code. ``dataset_input`` makes a
data file a run input (its DVC md5 as digest); ``save_runs_view`` and ``runs_view_url`` give
a lead the runs list with the columns that compare methods.
"""

from rigmap.tracking.champion import CHAMPION, champion_uri, promote_if_better
from rigmap.tracking.datasets import DataFile, dataset_input, dataset_inputs, file_md5
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
from rigmap.tracking.views import (
    TABLE1_VIEW,
    ViewNotFoundError,
    lead_view_url,
    runs_view_state,
    runs_view_url,
    save_runs_view,
    ui_base_url,
    view_id,
)

__all__ = [
    "CHAMPION",
    "TABLE1_VIEW",
    "DataFile",
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
    "ViewNotFoundError",
    "allow_mapping_class",
    "allowed_mapping_classes",
    "champion_uri",
    "check_reachable",
    "dataset_input",
    "dataset_inputs",
    "default_tracking_uri",
    "experiment_name",
    "file_md5",
    "flatten_config",
    "joint_columns",
    "lead_view_url",
    "load_pyfunc_model",
    "log_inverse_mapping",
    "log_method_run",
    "method_metrics",
    "promote_if_better",
    "registered_model_name",
    "resolve_tracking_uri",
    "runs_view_state",
    "runs_view_url",
    "safe_name",
    "save_runs_view",
    "start_parent_run",
    "ui_base_url",
    "view_id",
]
