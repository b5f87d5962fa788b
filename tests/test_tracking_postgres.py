"""MLflow on PostgreSQL through `scripts/tracking_server.sh`: runs, system metrics, and the
``champion`` alias of a registered mapping, loaded back by ``models:/…@champion``."""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from rigmap.tracking import (
    MappingToLog,
    Tracker,
    TrackingUnavailableError,
    log_method_run,
    start_parent_run,
)
from rigmap.tracking.champion import CHAMPION, champion_uri, promote_if_better
from test_tracking import evaluation  # noqa: F401  (the fixture: a small real biped evaluation

REGRESSOR = "least_squares_pg"


def test_runs_champion_and_system_metrics_on_postgresql(pg_tracking_server, evaluation):  # noqa: F811
    import mlflow
    import psycopg2

    tracker = Tracker.open(pg_tracking_server.uri, system_metrics_interval_s=1.0)
    model = MappingToLog(
        evaluation["mapping"],
        REGRESSOR,
        input_columns=list(evaluation["X_test"].columns),
        output_columns=evaluation["used_names"],
        input_example=evaluation["X_test"].iloc[:2],
    )
    summary = evaluation["result"].to_dict()
    worse = {**summary, "average": {**summary["average"]}}
    worse["average"]["joint_error"] = 10.0 * summary["average"]["joint_error"]
    with start_parent_run(tracker, "biped", name="pg-sweep") as parent:
        best = log_method_run(parent, rig="biped", method="lsq", sampler="none", kernel=None,
                              refine=None, result=summary, model=model, config=None)  # fmt: skip
        later = log_method_run(parent, rig="biped", method="lsq_worse", sampler="none",
                               kernel=None, refine=None, result=worse, model=model,
                               config=None)  # fmt: skip
        time.sleep(1.5)  # at least one system-metrics sample
    client = tracker.client
    name = best.model.registered_name
    assert (best.model.version, later.model.version) == ("1", "2")
    # the worse version did not take the alias; a better score moves it
    assert client.get_model_version_by_alias(name, CHAMPION).version == "1"
    assert promote_if_better(client, name, "2", 0.5 * summary["average"]["joint_error"])
    assert client.get_model_version_by_alias(name, CHAMPION).version == "2"
    mlflow.set_tracking_uri(pg_tracking_server.uri)
    loaded = mlflow.pyfunc.load_model(champion_uri("biped", REGRESSOR))
    predicted = np.asarray(loaded.predict(evaluation["X_test"]))
    assert np.allclose(predicted, evaluation["mapping"].predict(evaluation["X_test"].to_numpy()))
    metrics = client.get_run(parent.run_id).data.metrics
    assert any(k.startswith("system/cpu_utilization") for k in metrics), sorted(metrics)
    # the runs are rows of the PostgreSQL database, not of a file store
    dsn = pg_tracking_server.backend.replace("postgresql+psycopg2", "postgresql")
    with psycopg2.connect(dsn) as db, db.cursor() as cursor:
        cursor.execute("SELECT count(*) FROM runs WHERE run_uuid IN (%s, %s, %s)",
                       (parent.run_id, best.run_id, later.run_id))  # fmt: skip
        assert cursor.fetchone()[0] == 3


def test_postgresql_not_running_is_a_clear_error():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    uri = f"postgresql+psycopg2://rigmap@127.0.0.1:{port}/mlflow"
    with pytest.raises(TrackingUnavailableError, match=rf"PostgreSQL at 127.0.0.1:{port} does not"):
        Tracker.open(uri)


def test_tracking_config_takes_the_system_metrics_interval(pg_tracking_server, tmp_path):
    tracker = Tracker.from_config(
        {"uri": pg_tracking_server.uri, "system_metrics_interval_s": 2}, root=tmp_path
    )
    assert tracker.system_metrics_interval_s == 2.0
    with pytest.raises(ValueError, match="unknown fields \\['system_metrics'\\]"):
        Tracker.from_config({"system_metrics": True}, root=tmp_path)
