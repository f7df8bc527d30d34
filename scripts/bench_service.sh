#!/usr/bin/env bash
# Service load benchmark (numbers in docs/journal/BENCHMARKS_HISTORY.md): starts rigport-server
# on loopback with a fresh store, runs `rigport bench` against it and samples
# the server's resident memory every 5 s.
#   bash scripts/bench_service.sh [JOBS] [CONCURRENCY] [WORKERS] [CACHE_MB]
#   RIGPORT_BENCH_TLS=1 bash scripts/bench_service.sh ...   the same over HTTPS
# Uses the ICT rig onto id_s02_remesh (5.9k vertices) when ../shared/data is
# present, else the demo's generated rig and head. Needs build/release.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
JOBS="${1:-1000}"; CONCURRENCY="${2:-16}"; WORKERS="${3:-0}"; CACHE_MB="${4:-256}"
OUT="$(mktemp -d /tmp/rigport-bench.XXXXXX)"
source "$ROOT/scripts/service_bench_lib.sh"
rigport_bench_inputs "$OUT"
rigport_start_server "$OUT" "$WORKERS" "$CACHE_MB"
( while kill -0 $PID 2>/dev/null; do
    echo "$(date +%s) $(awk '/VmRSS/ {print $2}' /proc/$PID/status 2>/dev/null)" >> "$OUT/rss.txt"; sleep 5
  done ) &
"$BIN/client/rigport" bench --server "$URL" --concurrency "$CONCURRENCY" --jobs "$JOBS" --timeout 900 "${INPUTS[@]}" "${CLIENT_TLS[@]}" \
  2> "$OUT/bench.log" | tail -1 | tee "$OUT/bench.json"
# Server CPU per job: steadier than jobs/s on a noisy machine.
read -r UTIME STIME < <(awk '{print $14, $15}' /proc/$PID/stat)
python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); n=d["succeeded"]+d["failed"]; t=(int(sys.argv[2])+int(sys.argv[3]))/float(sys.argv[4]); print("server CPU %.1f s for %d jobs: %.1f ms per job" % (t, n, 1000*t/max(n,1)))' \
  "$OUT/bench.json" "$UTIME" "$STIME" "$(getconf CLK_TCK)"
awk '{ if ($2 > max) max = $2; if (min == "" || $2 < min) min = $2; n++; last = $2 }
     END { printf "server RSS over %d samples: min %.0f MiB, max %.0f MiB, last %.0f MiB (cache bound %s MiB)\n",
           n, min / 1024, max / 1024, last / 1024, "'"$CACHE_MB"'" }' "$OUT/rss.txt"
echo "logs and samples in $OUT"
