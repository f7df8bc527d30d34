#!/usr/bin/env bash
# Soak test (not in CI; numbers in docs/journal/BENCHMARKS_HISTORY.md): one rigport-server on
# loopback under `rigport bench` at CONCURRENCY clients for MINUTES, in
# back-to-back segments of SEGMENT_JOBS jobs (~10 s each on a 2-core machine).
# After each segment: jobs/s, p99, errors and the server's resident memory,
# one line of OUT/samples.tsv. At the end: totals, and whether memory levelled
# off (the last 10 minutes, or the second half of a shorter run, within 5%).
#   bash scripts/soak.sh [MINUTES=30] [CONCURRENCY=16] [SEGMENT_JOBS=400]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
MINUTES="${1:-30}"; CONCURRENCY="${2:-16}"; SEGMENT_JOBS="${3:-400}"
OUT="$(mktemp -d /tmp/rigport-soak.XXXXXX)"
source "$ROOT/scripts/service_bench_lib.sh"
rigport_bench_inputs "$OUT"
rigport_start_server "$OUT" 0 256
START="$(date +%s)"
END=$((START + MINUTES * 60))
printf 't_s\tjobs_per_s\tp99_ms\terrors\trss_mib\n' > "$OUT/samples.tsv"
while [ "$(date +%s)" -lt "$END" ]; do
  "$BIN/client/rigport" bench --server "$URL" --concurrency "$CONCURRENCY" --jobs "$SEGMENT_JOBS" --timeout 900 \
    "${INPUTS[@]}" "${CLIENT_TLS[@]}" 2>> "$OUT/bench.log" | tail -1 > "$OUT/segment.json"
  RSS_KB="$(awk '/VmRSS/ {print $2}' "/proc/$PID/status")"
  python3 - "$OUT/segment.json" "$(( $(date +%s) - START ))" "$RSS_KB" >> "$OUT/samples.tsv" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
errors = d["failed"] + d["unfinished"] + sum(d["errors_by_status"].values())
print("%s\t%.1f\t%.0f\t%d\t%.1f" % (sys.argv[2], d["jobs_per_s"], d["p99_ms"] or 0, errors, int(sys.argv[3]) / 1024))
PY
  tail -1 "$OUT/samples.tsv"
done
python3 - "$OUT/samples.tsv" <<'PY'
import statistics, sys
rows = [line.rstrip("\n").split("\t") for line in open(sys.argv[1])][1:]
t = [int(r[0]) for r in rows]; jps = [float(r[1]) for r in rows]; p99 = [float(r[2]) for r in rows]
errors = sum(int(r[3]) for r in rows); rss = [float(r[4]) for r in rows]
window = [m for ti, m in zip(t, rss) if ti >= t[-1] - 600] if t[-1] >= 1200 else rss[len(rss) // 2:]
spread = (max(window) - min(window)) / max(window)
print("soak: %d segments over %d s: jobs/s median %.1f (min %.1f), p99 median %.0f ms (max %.0f), errors %d"
      % (len(rows), t[-1], statistics.median(jps), min(jps), statistics.median(p99), max(p99), errors))
print("soak: RSS %.0f -> %.0f MiB (max %.0f); last window %.0f-%.0f MiB, spread %.1f%%: %s"
      % (rss[0], rss[-1], max(rss), min(window), max(window), 100 * spread,
         "levelled off" if spread <= 0.05 else "STILL GROWING"))
PY
echo "samples and logs in $OUT"
