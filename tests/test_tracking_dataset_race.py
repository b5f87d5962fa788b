"""Two stages side by side log the same dataset: the slower insert hits the store's unique
constraint, and rigmap tries again instead of failing the stage (ci33, session 46)."""

from __future__ import annotations

import pytest
import sqlalchemy.exc
from mlflow.exceptions import MlflowException

from rigmap.tracking import runs


class RacingClient:
    """``log_inputs`` fails as MLflow's SQL store does when another process inserted the same
    dataset between its lookup and its insert, ``losses`` times, then succeeds."""

    def __init__(self, losses: int, error: str = "unique"):
        self.losses, self.error, self.calls = losses, error, []

    def log_inputs(self, run_id, datasets):
        self.calls.append((run_id, list(datasets)))
        if len(self.calls) <= self.losses:
            if self.error != "unique":
                raise MlflowException("RESOURCE_DOES_NOT_EXIST: no run " + run_id)
            cause = sqlalchemy.exc.IntegrityError(
                "INSERT INTO datasets ...", {}, Exception("UNIQUE constraint failed: datasets.name")
            )
            raise MlflowException(f"({type(cause).__name__}) {cause}") from cause


def test_a_lost_insert_race_is_tried_again_and_links_the_dataset(monkeypatch):
    monkeypatch.setattr(runs.time, "sleep", lambda _: None)
    client = RacingClient(losses=2)
    runs.log_inputs(client, "run-1", ["corpus"])
    assert client.calls == [("run-1", ["corpus"])] * 3


def test_another_error_or_a_race_lost_every_time_is_raised(monkeypatch):
    monkeypatch.setattr(runs.time, "sleep", lambda _: None)
    other = RacingClient(losses=1, error="other")
    with pytest.raises(MlflowException, match="RESOURCE_DOES_NOT_EXIST"):
        runs.log_inputs(other, "run-1", ["corpus"])
    assert len(other.calls) == 1  # not a race: no second try
    always = RacingClient(losses=99)
    with pytest.raises(MlflowException, match="UNIQUE constraint"):
        runs.log_inputs(always, "run-1", ["corpus"])
    assert len(always.calls) == runs.DATASET_RETRIES + 1
