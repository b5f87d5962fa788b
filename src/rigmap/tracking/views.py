"""The lead's view: a saved view of the MLflow runs list and the link that opens it.

MLflow's UI keeps the runs list's columns in the browser, not in the URL; only its search
facets (filter, sort) travel in the URL. Its saved views (MLflow 3.17) are experiment tags
``mlflow.sharedViewState.<id>`` holding ``{"name", "createdAt", "updatedAt", "state"}``,
``state`` being the JSON of the facets and the table's columns, and the page
``#/experiments/<id>/runs?viewStateShareKey=<id>`` opens one (read from MLflow's own UI
bundle, mlflow/server/js). An evaluation saves one view per metrics set: its child runs
only (the filter keeps parents folded away), lowest joint error first, and beside each
method its joint error, ground-truth error and frames per second, then its datasets.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping, Sequence
from typing import Any
from urllib.parse import quote, urlsplit

from mlflow.utils.mlflow_tags import MLFLOW_PARENT_RUN_ID

from rigmap.errors import RigmapError

#: where MLflow 3.17's UI looks for saved views, and the URL key that opens one
VIEW_TAG_PREFIX = "mlflow.sharedViewState."
VIEW_URL_KEY = "viewStateShareKey"
#: our saved views are ``rigmap-<metrics set>``: ``rigmap-methods`` is Table 1
VIEW_PREFIX = "rigmap-"
TABLE1_VIEW = f"{VIEW_PREFIX}methods"
#: the columns a lead compares methods by (ours), in this order, then the run's datasets
LEAD_TAGS = ("method", "sampler")
LEAD_METRICS = ("joint_error", "ground_truth_error", "fps")
#: `mlflow ui`'s and `make tracking-server`'s address: the UI of a local (SQLite) store
DEFAULT_UI_URL = "http://127.0.0.1:5000"


class ViewNotFoundError(RigmapError, LookupError):
    """No saved view (or no experiment) where the link was asked for."""


def view_id(metrics_set: str) -> str:
    """The saved view of a metrics set (``methods``, ``methods_heldout``, ``samplers`` …)."""
    return f"{VIEW_PREFIX}{metrics_set}"


def column(kind: str, key: str) -> str:
    """A runs-table column as MLflow's UI names it: ``metrics.`joint_error```."""
    return f"{kind}.`{key}`"


def runs_view_state(
    parent_run_id: str,
    metrics: Sequence[str] = LEAD_METRICS,
    tags: Sequence[str] = LEAD_TAGS,
) -> dict[str, Any]:
    """The children of ``parent_run_id``, lowest ``metrics[0]`` first, with these columns."""
    columns = [
        *(column("tags", key) for key in tags),
        *(column("metrics", key) for key in metrics),
        column("attributes", "Dataset"),
    ]
    return {
        "searchFilter": f"{column('tags', MLFLOW_PARENT_RUN_ID)} = '{parent_run_id}'",
        "orderByKey": column("metrics", metrics[0]),
        "orderByAsc": True,
        "selectedColumns": columns,
        "columnOrder": columns,
    }


def save_runs_view(
    client: Any, experiment_id: str, view: str, name: str, state: Mapping[str, Any]
) -> None:
    """Save (or replace) the view ``view`` of the experiment's runs list under ``name``."""
    key = f"{VIEW_TAG_PREFIX}{view}"
    now = int(time.time() * 1000)
    created = now
    existing = client.get_experiment(experiment_id).tags.get(key)
    if existing:
        try:
            created = int(json.loads(existing)["createdAt"])
        except (ValueError, KeyError, TypeError):
            pass  # not a view envelope (an older UI's state): replaced whole
    envelope = {"name": name, "createdAt": created, "updatedAt": now, "state": json.dumps(state)}
    client.set_experiment_tag(experiment_id, key, json.dumps(envelope))


def saved_views(experiment: Any) -> dict[str, str]:
    """rigmap's saved views of an experiment: view id -> name."""
    views = {}
    for key, value in experiment.tags.items():
        view = key[len(VIEW_TAG_PREFIX) :] if key.startswith(VIEW_TAG_PREFIX) else ""
        if view.startswith(VIEW_PREFIX):
            try:
                views[view] = str(json.loads(value)["name"])
            except (ValueError, KeyError, TypeError):
                continue
    return views


def runs_view_url(base_url: str, experiment_id: str, view: str = TABLE1_VIEW) -> str:
    """The link that opens the saved view ``view`` of the experiment's runs list."""
    base = base_url.rstrip("/")
    return f"{base}/#/experiments/{quote(str(experiment_id))}/runs?{VIEW_URL_KEY}={quote(view)}"


def ui_base_url(tracking_uri: str) -> str | None:
    """The UI address of a tracking URI: a server's own; None for a local store (its UI is
    whatever `mlflow ui` is started on)."""
    if urlsplit(tracking_uri).scheme in ("http", "https"):
        return tracking_uri.rstrip("/")
    return None


def lead_view_url(tracker: Any, rig: str, view: str = TABLE1_VIEW, ui_url: str | None = None):
    """The link to ``rig``'s saved view ``view`` on ``tracker``'s store; one line naming what
    is missing (the experiment, or the view with the ones there are)."""
    from rigmap.tracking.runs import experiment_name

    name = experiment_name(rig, tracker.experiment_prefix)
    experiment = tracker.client.get_experiment_by_name(name)
    if experiment is None:
        raise ViewNotFoundError(
            f"no experiment {name!r} at {tracker.uri}: run the evaluate stage on rig {rig!r} "
            "with evaluate.log_to_mlflow=true first"
        )
    views = saved_views(experiment)
    if view not in views:
        there = ", ".join(sorted(views)) or "none"
        raise ViewNotFoundError(
            f"experiment {name!r} has no saved view {view!r} (there are: {there}); "
            "each evaluate run saves rigmap-<its metrics set>"
        )
    base = ui_url or ui_base_url(tracker.uri) or DEFAULT_UI_URL
    return runs_view_url(base, experiment.experiment_id, view)
