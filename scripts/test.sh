#!/usr/bin/env bash
# Installs dependencies, builds and runs the whole test suite with CTest.
#   bash scripts/test.sh              release build in build/release
#   bash scripts/test.sh --sanitize   debug build with ASan + UBSan in build/asan
# Tests that need ../shared/data skip with a message when it is absent.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

MODE=release
if [ "${1:-}" = "--sanitize" ]; then MODE=asan; fi

bash docker/install-deps.sh

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
  ctest --test-dir build/asan --output-on-failure -j "$JOBS"
else
  cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release -DRIGPORT_WERROR=ON
  cmake --build build/release -j "$JOBS"
  ctest --test-dir build/release --output-on-failure -j "$JOBS"
fi
