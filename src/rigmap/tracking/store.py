"""Where runs go: the tracking URI, the local default store, and a fast reachability check.

Precedence, most specific first: an explicit URI (argument or config
``tracking.uri``), then the ``MLFLOW_TRACKING_URI`` environment variable, then
the project's own SQLite store ``sqlite:///<project root>/mlruns.db`` with
artifacts in ``<project root>/mlartifacts`` — so ``mlflow ui`` on that file
shows every run made in the checkout.

MLflow's HTTP client retries a dead server with exponential backoff for
minutes. ``check_reachable`` instead asks ``GET <uri>/health`` with a short
timeout and fails at once with an error that names the URI.
"""

from __future__ import annotations

import os
import socket
import time
import urllib.error
import urllib.request
from collections.abc import Mapping
from pathlib import Path
from urllib.parse import urlsplit

from rigmap.errors import RigmapError
from rigmap.store.layout import TRACKING_STORE, Layout, find_project_root, source_checkout

TRACKING_URI_ENV = "MLFLOW_TRACKING_URI"
DEFAULT_STORE_FILE = TRACKING_STORE
DEFAULT_ARTIFACT_DIR = "mlartifacts"
DEFAULT_PROBE_TIMEOUT_S = 3.0
MAX_PROBE_TIMEOUT_S = 10.0  # ours: a check that waits longer than this is no early check

#: ours: one HTTP request to a tracking server waits at most this long, and is retried
#: this often, so a server that answers the probe and then stalls is named within 10 s
#: (MLflow's own defaults wait 120 s and retry 7 times)
DEFAULT_REQUEST_TIMEOUT_S = 4  # whole seconds: MLflow reads an integer
DEFAULT_REQUEST_RETRIES = 1
REQUEST_BACKOFF_FACTOR = 1  # ours, an integer as MLflow reads it: urllib3 retries once at once


class TrackingUnavailableError(RigmapError, RuntimeError):
    """The tracking store named by a URI cannot be used (server down, folder not writable)."""


def project_folder(root: str | os.PathLike | None = None) -> Path:
    """Where the project's own store lives: ``root`` if given, else the project at or above
    the working directory, else the checkout an editable install runs from
    (:func:`rigmap.store.layout.source_checkout`), else the working directory."""
    if root is not None:
        return Path(root).resolve()
    for start in (Path.cwd(), source_checkout()):
        found = find_project_root(start) if start is not None else None
        if found is not None:
            return found
    return Path.cwd().resolve()


def default_tracking_uri(root: str | os.PathLike | None = None) -> str:
    """``sqlite:///<project root>/mlruns.db`` (an absolute path, so any working directory works)."""
    return f"sqlite:///{Layout.tracking_store(project_folder(root))}"


def resolve_tracking_uri(
    uri: str | None = None,
    *,
    root: str | os.PathLike | None = None,
    environ: Mapping[str, str] | None = None,
) -> str:
    """The URI to log to: ``uri`` if given, else ``$MLFLOW_TRACKING_URI``, else the local store."""
    environ = os.environ if environ is None else environ
    for candidate in (uri, environ.get(TRACKING_URI_ENV)):
        if candidate is not None and str(candidate).strip():
            return _absolute_local_uri(str(candidate).strip())
    return default_tracking_uri(root)


def _absolute_local_uri(uri: str) -> str:
    """Make a relative ``sqlite:///file.db`` absolute, so artifacts land beside the file."""
    if uri.startswith("sqlite:///") and not uri.startswith("sqlite:////"):
        path = uri.removeprefix("sqlite:///")
        if path and path != ":memory:":
            return f"sqlite:///{Path(path).resolve()}"
    return uri


def local_artifact_root(uri: str) -> Path | None:
    """Where a local SQLite store keeps artifacts (``mlartifacts`` beside the database file).

    ``None`` for stores that decide themselves: a server (``mlflow-artifacts:/``),
    a file store (artifacts inside it), or a remote database.
    """
    if uri.startswith("sqlite:///"):
        path = uri.removeprefix("sqlite:///")
        if path and path != ":memory:":
            return Path(path).parent / DEFAULT_ARTIFACT_DIR
    return None


def is_http_uri(uri: str) -> bool:
    return urlsplit(uri).scheme in ("http", "https")


def check_reachable(uri: str, timeout_s: float = DEFAULT_PROBE_TIMEOUT_S) -> None:
    """Fail fast, naming ``uri``, if the store cannot be used.

    HTTP(S): ``GET <uri>/health`` must answer 200 within ``timeout_s``. SQLite:
    the database's folder must exist or be creatable, and be writable.
    """
    scheme = urlsplit(uri).scheme
    if scheme in ("http", "https"):
        _probe_server(uri, timeout_s)
    elif scheme == "sqlite":
        path = uri.removeprefix("sqlite:///")
        if path and path != ":memory:" and uri.startswith("sqlite:///"):
            _check_writable_folder(Path(path).parent, uri)
    elif scheme in ("", "file"):
        _check_writable_folder(Path(urlsplit(uri).path or uri), uri)
    elif scheme.startswith("postgresql"):
        _probe_database(uri, timeout_s)


def _probe_database(uri: str, timeout_s: float) -> None:
    """A PostgreSQL store (``postgresql+psycopg2://user@host:port/db``) must accept a TCP
    connection within ``timeout_s``; the error names the address and how to start one."""
    parts = urlsplit(uri)
    host, port = parts.hostname or "127.0.0.1", parts.port or 5432
    try:
        with socket.create_connection((host, port), timeout=min(timeout_s, MAX_PROBE_TIMEOUT_S)):
            pass
    except OSError as error:
        raise TrackingUnavailableError(
            f"MLflow tracking store {parts.scheme}://{host}:{port}{parts.path} is unusable: "
            f"PostgreSQL at {host}:{port} does not accept connections "
            f"({_connection_failure(error, timeout_s)}). Start it with "
            "`bash scripts/tracking_server.sh start` (PostgreSQL + mlflow server; then use "
            "tracking=server), or leave tracking.uri null for the local store."
        ) from None


def _probe_server(uri: str, timeout_s: float) -> None:
    """One ``GET /health`` bounded by ``timeout_s`` (at most ``MAX_PROBE_TIMEOUT_S``).

    The error says which of the three ways it failed: nothing listening (closed
    port), no answer in time (a hung server), or an error status (a failing server).
    """
    timeout_s = min(float(timeout_s), MAX_PROBE_TIMEOUT_S)
    health = uri.rstrip("/") + "/health"
    started = time.perf_counter()
    try:
        with urllib.request.urlopen(health, timeout=timeout_s) as response:
            status = response.status
            response.read(64)
    except urllib.error.HTTPError as error:
        status, reason = error.code, f"it answers HTTP {error.code}: the server is failing"
    except (urllib.error.URLError, OSError) as error:
        status, reason = None, _connection_failure(getattr(error, "reason", error), timeout_s)
    else:
        reason = f"it answers HTTP {status}, expected 200"
    if status == 200:
        return
    waited = time.perf_counter() - started
    raise TrackingUnavailableError(
        f"MLflow tracking server {uri} is unusable: GET {health} failed after {waited:.1f} s "
        f"(timeout {timeout_s:g} s; {reason}). Start it (this project's: `bash "
        f"scripts/tracking_server.sh start`, MLflow on PostgreSQL at http://127.0.0.1:5000; or "
        f"`mlflow server --host 127.0.0.1 --port <port>`), or log to the local store instead: "
        f"unset {TRACKING_URI_ENV} and "
        f"leave tracking.uri null (default {default_tracking_uri()})."
    )


def _connection_failure(reason: object, timeout_s: float) -> str:
    if isinstance(reason, ConnectionRefusedError):
        return "connection refused: nothing listens on that port"
    if isinstance(reason, TimeoutError | socket.timeout) or "timed out" in str(reason):
        return f"no answer within {timeout_s:g} s: the server accepts connections but hangs"
    return str(reason)


def _check_writable_folder(folder: Path, uri: str) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise TrackingUnavailableError(
            f"tracking store {uri}: cannot create folder {folder} ({error.strerror})"
        ) from None
    if not os.access(folder, os.W_OK):
        raise TrackingUnavailableError(f"tracking store {uri}: folder {folder} is not writable")


def bound_http_retries(
    timeout_s: int = DEFAULT_REQUEST_TIMEOUT_S, retries: int = DEFAULT_REQUEST_RETRIES
) -> None:
    """Bound every MLflow HTTP request: ``timeout_s`` per attempt, ``retries`` more attempts.

    The values come from ``tracking.request_timeout_s`` / ``tracking.request_retries``
    (one setting for every call rigmap makes); MLflow reads these variables per request.
    """
    if isinstance(timeout_s, bool) or int(timeout_s) != timeout_s or timeout_s < 1:
        raise ValueError(f"tracking.request_timeout_s must be whole seconds >= 1, got {timeout_s}")
    if isinstance(retries, bool) or int(retries) != retries or retries < 0:
        raise ValueError(f"tracking.request_retries must be an integer >= 0, got {retries}")
    os.environ["MLFLOW_HTTP_REQUEST_TIMEOUT"] = str(int(timeout_s))
    os.environ["MLFLOW_HTTP_REQUEST_MAX_RETRIES"] = str(int(retries))
    os.environ["MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR"] = str(REQUEST_BACKOFF_FACTOR)


def tracking_failure(error: BaseException) -> TrackingUnavailableError | None:
    """The one-line error for an MLflow call that found no answer (a server that stalls or
    went away mid-run), or ``None`` when ``error`` is something else."""
    from mlflow.exceptions import MlflowException

    if not isinstance(error, MlflowException):
        return None
    text = str(error.message if hasattr(error, "message") else error)
    if "API request to" not in text:
        return None
    endpoint = text.split("API request to", 1)[1].split()[0]
    reason = "timed out" if "timed out" in text.lower() else "failed"
    timeout = os.environ.get("MLFLOW_HTTP_REQUEST_TIMEOUT", "?")
    retries = os.environ.get("MLFLOW_HTTP_REQUEST_MAX_RETRIES", "?")
    return TrackingUnavailableError(
        f"the tracking server did not answer {endpoint} ({reason} after {retries} "
        f"retr{'y' if retries == '1' else 'ies'} of {timeout} s; tracking.request_timeout_s "
        "and tracking.request_retries set these)"
    )
