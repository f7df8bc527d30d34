#!/usr/bin/env bash
# Installs dependencies, builds and runs the whole test suite with CTest.
#   bash scripts/test.sh              release build in build/release
#   bash scripts/test.sh --sanitize   debug build with ASan + UBSan in build/asan
# Tests that need ../shared/data skip with a message when it is absent. The
# PostgreSQL store's tests run against a temporary cluster started here
# (scripts/postgres.sh), or the server RIGPORT_TEST_POSTGRES_URL names.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

MODE=release
if [ "${1:-}" = "--sanitize" ]; then MODE=asan; fi

bash docker/install-deps.sh

# The tests that need PostgreSQL connect to RIGPORT_TEST_POSTGRES_URL: a server
# the caller names, or else a temporary cluster (scripts/postgres.sh) for this
# run only, stopped and removed on exit whatever the tests' outcome (its
# directory is kept when the run fails, for its postgres.log).
PG_DIR=""
stop_postgres() {
  local rc=$?
  if [ -n "$PG_DIR" ]; then
    bash scripts/postgres.sh stop "$PG_DIR" || true
    if [ "$rc" -eq 0 ]; then rm -rf "$PG_DIR"; else echo "test.sh: PostgreSQL log kept in $PG_DIR/postgres.log" >&2; fi
  fi
  exit "$rc"
}
start_postgres() {
  if [ -n "${RIGPORT_TEST_POSTGRES_URL:-}" ]; then return; fi
  # Under /tmp, where the postgres user can reach it, one per run: the release
  # and sanitize runs never share one.
  PG_DIR="$(mktemp -d "/tmp/rigport-pg-$MODE.XXXXXX")"
  trap stop_postgres EXIT
  trap 'exit 130' INT
  trap 'exit 143' TERM
  RIGPORT_TEST_POSTGRES_URL="$(bash scripts/postgres.sh start "$PG_DIR")"
  export RIGPORT_TEST_POSTGRES_URL
  echo "test.sh: PostgreSQL for the tests at $RIGPORT_TEST_POSTGRES_URL"
}

JOBS="$(nproc 2>/dev/null || echo 2)"
if [ "$MODE" = asan ]; then
  # -O1 keeps asserts (no NDEBUG) and sanitizer reports exact enough, and makes
  # the Eigen-heavy jobs of the service tests ~10x faster than -O0. -g1 (line
  # tables: reports still name function, file and line) compiles ~1.5x faster
  # than full debug info of Eigen's templates.
  cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" \
    -DRIGPORT_SANITIZE=ON -DRIGPORT_WERROR=ON -DRIGPORT_BUILD_BENCHMARKS=OFF
  cmake --build build/asan -j "$JOBS"
  export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1"
  export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
  start_postgres
  ctest --test-dir build/asan --output-on-failure -j "$JOBS"
else
  cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIGPORT_WERROR=ON
  cmake --build build/release -j "$JOBS"
  start_postgres
  ctest --test-dir build/release --output-on-failure -j "$JOBS"
fi
