#!/usr/bin/env bash
# Installs dependencies, builds rigport, and runs the main job through the
# service on data the project generates itself: a procedural source rig and a
# target head of other proportions and topology. The script starts
# rigport-server on loopback with its embedded store (demo-out/store), uploads
# the rig and submits the transfer with the rigport client, downloads the
# rigged GLB and diagnostics, checks them against the in-process run, and stops
# the server. Outputs go to demo-out/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

bash docker/install-deps.sh
cmake -S . -B build/release -G Ninja -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build/release -j "$(nproc 2>/dev/null || echo 2)" --target rigport rigport-server
RIGPORT=./build/release/client/rigport
OUT=demo-out
mkdir -p "$OUT"

# 1. Inputs: a generated rig (skeleton, weights, shapes, clip) and a target head.
"$RIGPORT" demo --out "$OUT" --inputs-only

# 2. The service on an ephemeral loopback port; its first stdout line names the port.
rm -rf "$OUT/store"
./build/release/server/rigport-server --listen 127.0.0.1:0 --data-dir "$OUT/store" --no-auth \
  > "$OUT/server.out" 2> "$OUT/server.log" &
SERVER_PID=$!
trap 'kill -TERM "$SERVER_PID" 2>/dev/null || true' EXIT
for _ in $(seq 1 100); do
  grep -q "listening on" "$OUT/server.out" 2>/dev/null && break
  sleep 0.1
done
URL="$(sed -n 's/^listening on //p' "$OUT/server.out")"
[ -n "$URL" ] || { echo "demo: rigport-server did not start (see $OUT/server.log)"; exit 1; }
echo "demo: rigport-server at $URL (store $OUT/store, logs $OUT/server.log)"

# 3. The transfer through the service: upload, submit, progress, download.
"$RIGPORT" transfer --server "$URL" \
  --source "$OUT/source_rig.glb" --source-landmarks "$OUT/source_rig.landmarks.json" \
  --target "$OUT/target_head.glb" --target-landmarks "$OUT/target_head.landmarks.json" \
  -o "$OUT/out.glb" --diagnostics "$OUT/diagnostics.json" --print-diagnostics

# 4. Graceful stop (SIGTERM: running jobs finish, queued ones stay in the store).
kill -TERM "$SERVER_PID"
wait "$SERVER_PID" || true
trap - EXIT

# 5. The same transfer in-process must give the same bytes.
"$RIGPORT" -q transfer --source "$OUT/source_rig.glb" --source-landmarks "$OUT/source_rig.landmarks.json" \
  --target "$OUT/target_head.glb" --target-landmarks "$OUT/target_head.landmarks.json" -o "$OUT/out.local.glb"
if cmp -s "$OUT/out.glb" "$OUT/out.local.glb"; then
  echo "demo: service result $OUT/out.glb is byte-identical to the in-process run"
else
  echo "demo: service result differs from the in-process run"; exit 1
fi
