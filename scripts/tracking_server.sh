#!/usr/bin/env bash
# MLflow tracking server on PostgreSQL, on this machine (conf/tracking/server.yaml talks to it).
#
#   bash scripts/tracking_server.sh start   # PostgreSQL (initdb once, pg_ctl) + mlflow server
#   bash scripts/tracking_server.sh status
#   bash scripts/tracking_server.sh stop
#
# Everything lives in RIGMAP_TRACKING_DIR (default <repo>/.tracking): pgdata/ (the database
# cluster), artifacts/ (what runs log), logs, pid files. Ports: RIGMAP_PG_PORT (5433) and
# RIGMAP_MLFLOW_PORT (5000), both on 127.0.0.1. `start` prints the MLFLOW_TRACKING_URI to use.
# The backend URI names psycopg2 (psycopg2-binary, in the scale extra): SQLAlchemy 2.1 would
# otherwise look for psycopg 3.
# PostgreSQL refuses to run as root: as root the cluster belongs to the `postgres` user
# (created by the Debian package; `apt-get install -y postgresql` when it is missing).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
DIR="${RIGMAP_TRACKING_DIR:-$REPO/.tracking}"
PG_PORT="${RIGMAP_PG_PORT:-5433}"
ML_PORT="${RIGMAP_MLFLOW_PORT:-5000}"
MLFLOW="${RIGMAP_MLFLOW:-$REPO/.venv/bin/mlflow}"
DB=mlflow
DB_USER=rigmap
START_TIMEOUT_S="${RIGMAP_TRACKING_START_TIMEOUT_S:-120}"
STOP_GRACE_S="${RIGMAP_TRACKING_STOP_GRACE_S:-10}"  # SIGTERM to SIGKILL of mlflow server

die() { echo "tracking_server.sh: $*" >&2; exit 1; }

pg_bindir() {
  if command -v pg_config >/dev/null 2>&1 && [ -x "$(pg_config --bindir)/pg_ctl" ]; then
    pg_config --bindir; return
  fi
  local found
  found="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1 || true)"
  [ -n "$found" ] && [ -x "$found/pg_ctl" ] && { echo "$found"; return; }
  return 1
}

ensure_postgres() {
  if ! BIN="$(pg_bindir)"; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
      echo "PostgreSQL not found: apt-get install -y postgresql" >&2
      DEBIAN_FRONTEND=noninteractive apt-get install -y -q postgresql >/dev/null \
        || die "apt-get install postgresql failed; install PostgreSQL (initdb, pg_ctl) yourself"
      BIN="$(pg_bindir)" || die "PostgreSQL installed but pg_ctl not found"
    else
      die "PostgreSQL not found (no pg_ctl in /usr/lib/postgresql/*/bin or pg_config --bindir); \
install it (Debian: apt-get install postgresql)"
    fi
  fi
}

# PostgreSQL's programs, as the cluster's owner when we are root
as_owner() {
  if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}

pg_running() { as_owner "$BIN/pg_ctl" -D "$DIR/pgdata" status >/dev/null 2>&1; }

mlflow_running() {
  [ -f "$DIR/mlflow.pid" ] && kill -0 "$(cat "$DIR/mlflow.pid")" 2>/dev/null
}

port_free() {
  ! (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null
}

start() {
  ensure_postgres
  [ -x "$MLFLOW" ] || die "no mlflow at $MLFLOW: run make setup (or set RIGMAP_MLFLOW)"
  mkdir -p "$DIR/artifacts" "$DIR/run"
  if [ "$(id -u)" = 0 ]; then
    id postgres >/dev/null 2>&1 || die "running as root needs the 'postgres' user to own the \
cluster (apt-get install postgresql creates it)"
    mkdir -p "$DIR/pgdata"
    chown postgres "$DIR/pgdata" "$DIR/run"
    chmod 700 "$DIR/pgdata"
    # postgres must be able to reach the folder
    as_owner test -x "$DIR" || die "user postgres cannot enter $DIR; choose RIGMAP_TRACKING_DIR \
on a path every user can traverse"
  fi
  if [ ! -f "$DIR/pgdata/PG_VERSION" ]; then
    as_owner "$BIN/initdb" -D "$DIR/pgdata" -U "$DB_USER" --auth=trust -E UTF8 >"$DIR/initdb.log" 2>&1 \
      || die "initdb failed: $(tail -n 5 "$DIR/initdb.log")"
  fi
  if ! pg_running; then
    port_free "$PG_PORT" || die "port $PG_PORT is taken: set RIGMAP_PG_PORT"
    touch "$DIR/postgres.log"; [ "$(id -u)" = 0 ] && chown postgres "$DIR/postgres.log"
    as_owner "$BIN/pg_ctl" -D "$DIR/pgdata" -l "$DIR/postgres.log" -w -t "$START_TIMEOUT_S" \
      -o "-p $PG_PORT -k $DIR/run -c listen_addresses=127.0.0.1" start >/dev/null \
      || die "PostgreSQL did not start: $(tail -n 5 "$DIR/postgres.log")"
  fi
  if ! "$BIN/psql" -h 127.0.0.1 -p "$PG_PORT" -U "$DB_USER" -d postgres -tAc \
      "SELECT 1 FROM pg_database WHERE datname='$DB'" | grep -q 1; then
    "$BIN/createdb" -h 127.0.0.1 -p "$PG_PORT" -U "$DB_USER" "$DB"
  fi
  local backend="postgresql+psycopg2://$DB_USER@127.0.0.1:$PG_PORT/$DB"
  if ! mlflow_running; then
    port_free "$ML_PORT" || die "port $ML_PORT is taken: set RIGMAP_MLFLOW_PORT"
    MLFLOW_SERVER_ENABLE_JOB_EXECUTION=false setsid "$MLFLOW" server \
      --host 127.0.0.1 --port "$ML_PORT" --workers 1 \
      --backend-store-uri "$backend" --artifacts-destination "$DIR/artifacts" \
      >"$DIR/mlflow.log" 2>&1 < /dev/null &
    echo $! >"$DIR/mlflow.pid"
    local deadline=$((SECONDS + START_TIMEOUT_S))
    until curl -fsS "http://127.0.0.1:$ML_PORT/health" >/dev/null 2>&1; do
      mlflow_running || die "mlflow server exited: $(tail -n 20 "$DIR/mlflow.log")"
      [ $SECONDS -lt $deadline ] || die "mlflow server not up in ${START_TIMEOUT_S}s: \
$(tail -n 20 "$DIR/mlflow.log")"
      sleep 0.5
    done
  fi
  echo "backend: $backend"
  echo "artifacts: $DIR/artifacts"
  echo "MLFLOW_TRACKING_URI=http://127.0.0.1:$ML_PORT"
}

stop() {
  if mlflow_running; then
    local pid; pid="$(cat "$DIR/mlflow.pid")"
    kill -TERM -- "-$pid" 2>/dev/null || kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq $((STOP_GRACE_S * 5))); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    kill -KILL -- "-$pid" 2>/dev/null || true
  fi
  rm -f "$DIR/mlflow.pid"
  if BIN="$(pg_bindir)" && [ -f "$DIR/pgdata/PG_VERSION" ] && pg_running; then
    as_owner "$BIN/pg_ctl" -D "$DIR/pgdata" -m fast -w stop >/dev/null || true
  fi
  echo "stopped"
}

status() {
  BIN="$(pg_bindir)" || die "PostgreSQL not installed"
  if [ -f "$DIR/pgdata/PG_VERSION" ] && pg_running; then echo "postgresql: running on $PG_PORT"
  else echo "postgresql: stopped"; fi
  if mlflow_running; then echo "mlflow: running on http://127.0.0.1:$ML_PORT"
  else echo "mlflow: stopped"; fi
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  status) status ;;
  *) die "usage: $0 start|stop|status" ;;
esac
