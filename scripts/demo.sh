#!/usr/bin/env bash
# Installs dependencies, builds rigport and runs the main job on data the
# project generates itself: a procedural source head warped onto a target head
# of other proportions and topology. Outputs and diagnostics go to demo-out/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash docker/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build/release -j "$(nproc 2>/dev/null || echo 2)" --target rigport
./build/release/client/rigport demo --out demo-out
