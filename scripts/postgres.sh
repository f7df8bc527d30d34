#!/usr/bin/env bash
# A temporary PostgreSQL cluster for the tests, which need a real server: one
# cluster per test run, in a directory of its own, listening on 127.0.0.1 only
# (plus a unix socket in that directory), run by an unprivileged user (initdb
# and postgres refuse root, so as root it runs them as Debian's `postgres`).
#   bash scripts/postgres.sh start DIR [PORT]   initdb if DIR/data is absent, start,
#                                               print the connection URL (one line)
#   bash scripts/postgres.sh stop DIR           fast shutdown; fine if not running
#   bash scripts/postgres.sh url DIR            print the URL of the running cluster
# The URL names user `rigport` (trust auth, loopback only) and database
# `rigport_test`, both created on first start. Without PORT, a free port from
# 55432 upward is picked; the port is kept in DIR/port and reused on restart.
# The log is DIR/postgres.log. Server packages: docker/install-deps.sh.
set -euo pipefail

die() { echo "postgres.sh: $*" >&2; exit 1; }
usage() { die "usage: postgres.sh start DIR [PORT] | stop DIR | url DIR"; }

CMD="${1:-}"
DIR="${2:-}"
if [ -z "$CMD" ] || [ -z "$DIR" ]; then usage; fi
case "$CMD" in start) [ "$#" -le 3 ] || usage ;; stop|url) [ "$#" -eq 2 ] || usage ;; *) usage ;; esac
REQ_PORT="${3:-}"
if [ -n "$REQ_PORT" ] && ! [[ "$REQ_PORT" =~ ^[0-9]+$ && "$REQ_PORT" -ge 1024 && "$REQ_PORT" -le 65535 ]]; then
  die "PORT must be a number from 1024 to 65535, not '$REQ_PORT'"
fi

# Newest installed server version.
BIN="$(printf '%s\n' /usr/lib/postgresql/*/bin | sort -V | tail -n 1)"
if [ ! -x "$BIN/initdb" ] || [ ! -x "$BIN/pg_ctl" ]; then
  die "no PostgreSQL server found under /usr/lib/postgresql/*/bin (install it with: bash docker/install-deps.sh)"
fi

if [ ! -d "$DIR" ]; then
  case "$CMD" in
    start) mkdir -p "$DIR" ;;
    stop) echo "postgres.sh: no server running in $DIR (no such directory)" >&2; exit 0 ;;
    url) die "no cluster in $DIR (no such directory): run 'postgres.sh start $DIR'" ;;
  esac
fi
DIR="$(cd "$DIR" && pwd)"
DATA="$DIR/data"
# The unix socket is DIR/.s.PGSQL.PORT, and a socket path has at most 107 bytes.
[ "${#DIR}" -le 90 ] || die "DIR is too long for a unix socket path (${#DIR} > 90 characters): $DIR"
LOG="$DIR/postgres.log"
PORT_FILE="$DIR/port"
DB_USER=rigport
DB_NAME=rigport_test

# As root, run the server's tools as the `postgres` system user.
if [ "$(id -u)" -eq 0 ]; then
  id postgres >/dev/null 2>&1 || die "no 'postgres' system user (it comes with Debian's postgresql package: bash docker/install-deps.sh)"
  SUPERUSER=postgres
  AS=(runuser -u postgres --)
else
  SUPERUSER="$(id -un)"
  AS=()
fi
# From / so that a working directory closed to that user (/root) does not matter.
as_pg() { (cd / && "${AS[@]}" "$@"); }

url_for() { echo "postgresql://$DB_USER@127.0.0.1:$1/$DB_NAME"; }
stored_port() { [ -f "$PORT_FILE" ] && cat "$PORT_FILE"; }
running() { [ -f "$DATA/PG_VERSION" ] && as_pg "$BIN/pg_ctl" status -D "$DATA" >/dev/null 2>&1; }
port_busy() { timeout 1 bash -c "exec 3<>/dev/tcp/127.0.0.1/$1" 2>/dev/null; }

# Waits up to 30 s until the server accepts TCP connections on 127.0.0.1:$1.
wait_ready() {
  local _
  for _ in $(seq 1 60); do
    "$BIN/pg_isready" -q -h 127.0.0.1 -p "$1" -U "$DB_USER" -d "$DB_NAME" -t 1 && return 0
    sleep 0.5
  done
  die "server in $DIR does not accept connections on 127.0.0.1:$1 after 30 s; see $LOG"
}

cmd_url() {
  local port
  port="$(stored_port)" || die "no cluster in $DIR (no $PORT_FILE): run 'postgres.sh start $DIR'"
  running || die "the cluster in $DIR is not running: run 'postgres.sh start $DIR'"
  url_for "$port"
}

cmd_stop() {
  if running; then
    as_pg "$BIN/pg_ctl" stop -D "$DATA" -m fast -w -t 30 >/dev/null \
      || die "could not stop the server in $DIR; see $LOG"
  else
    echo "postgres.sh: no server running in $DIR" >&2
  fi
}

# Tries one start on port $1: 0 when it accepts connections, 2 when the port was
# taken (by another process, between the check and the bind), 1 otherwise.
try_start() {
  local port="$1" before
  before="$(stat -c %s "$LOG" 2>/dev/null || echo 0)"
  # fd 9 (the port lock) must not leak into the server, which outlives this script.
  if as_pg "$BIN/pg_ctl" start -D "$DATA" -l "$LOG" -w -t 30 -o "-p $port" >/dev/null 9>&-; then
    return 0
  fi
  if tail -c +"$((before + 1))" "$LOG" 2>/dev/null | grep -q "Address already in use"; then
    return 2
  fi
  return 1
}

cmd_start() {
  if running; then
    local port
    port="$(stored_port)" || die "a server runs in $DIR but $PORT_FILE is missing; stop it with 'postgres.sh stop $DIR'"
    wait_ready "$port"
    url_for "$port"
    return
  fi

  # The directory must belong to the user that runs the server, and the path to
  # it must be traversable by that user.
  if [ "$(id -u)" -eq 0 ]; then chown postgres:postgres "$DIR"; fi
  chmod 700 "$DIR"
  as_pg test -w "$DIR" || die "user $SUPERUSER cannot write to $DIR (is a parent directory closed to it?); use a directory under /tmp"

  if [ ! -f "$DATA/PG_VERSION" ]; then
    # A half-made data directory from an interrupted initdb is started over.
    rm -rf "$DATA"
    as_pg "$BIN/initdb" -D "$DATA" -U "$SUPERUSER" -E UTF8 --locale=C \
      --auth-local=peer --auth-host=reject >"$DIR/initdb.log" 2>&1 \
      || die "initdb failed; see $DIR/initdb.log"
    cat >>"$DATA/postgresql.conf" <<EOF

# scripts/postgres.sh: a test cluster, loopback only, socket in its own directory.
listen_addresses = '127.0.0.1'
unix_socket_directories = '$DIR'
fsync = on
EOF
    # The superuser through the socket (peer), user rigport on loopback (trust);
    # nothing else.
    cat >"$DATA/pg_hba.conf" <<EOF
# TYPE  DATABASE  USER          ADDRESS        METHOD
local   all       $SUPERUSER    peer
host    all       $DB_USER      127.0.0.1/32   trust
EOF
  fi

  # Choose and bind the port under a lock, so that clusters started at the same
  # time get different ports.
  exec 9>/tmp/rigport-postgres-port.lock
  flock -w 120 9 || die "timed out waiting for /tmp/rigport-postgres-port.lock"
  local candidates port="" p rc
  if [ -n "$REQ_PORT" ]; then
    port_busy "$REQ_PORT" && die "port $REQ_PORT on 127.0.0.1 is already in use"
    candidates="$REQ_PORT"
  else
    candidates="$(stored_port || true) $(seq 55432 55531)"
  fi
  for p in $candidates; do
    [ -z "$REQ_PORT" ] && port_busy "$p" && continue
    rc=0; try_start "$p" || rc=$?
    if [ "$rc" -eq 0 ]; then port="$p"; break; fi
    if [ "$rc" -eq 2 ] && [ -z "$REQ_PORT" ]; then continue; fi
    die "the server in $DIR did not start on port $p; see $LOG"
  done
  exec 9>&-
  [ -n "$port" ] || die "no free port in 55432-55531 on 127.0.0.1; see $LOG"
  echo "$port" >"$PORT_FILE"

  wait_ready "$port"
  # User and database, created once (checked on every start, in case a first
  # start was interrupted).
  local psql=(as_pg "$BIN/psql" -X -q -h "$DIR" -p "$port" -U "$SUPERUSER" -d postgres -v ON_ERROR_STOP=1 -tA)
  if [ -z "$("${psql[@]}" -c "SELECT 1 FROM pg_roles WHERE rolname = '$DB_USER'")" ]; then
    "${psql[@]}" -c "CREATE ROLE $DB_USER LOGIN CREATEDB" >/dev/null || die "could not create user $DB_USER; see $LOG"
  fi
  if [ -z "$("${psql[@]}" -c "SELECT 1 FROM pg_database WHERE datname = '$DB_NAME'")" ]; then
    "${psql[@]}" -c "CREATE DATABASE $DB_NAME OWNER $DB_USER" >/dev/null || die "could not create database $DB_NAME; see $LOG"
  fi
  url_for "$port"
}

case "$CMD" in
  start) cmd_start ;;
  stop) cmd_stop ;;
  url) cmd_url ;;
esac
