#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz (clang, ASan + UBSan) in
# build/fuzz and runs each for SECONDS (default 30; CI's smoke run), seeded
# from files the project generates itself, a few hand-written ones, and the
# glTF, OBJ, PLY, TRC and landmark files of ../shared/data when present.
# Any finding (crash, leak, out-of-bounds read, an input over 60 s, out-of-memory) fails
# the run; its input is kept in build/fuzz/findings/<target>/ (make it a
# regression test). Long runs and their numbers: docs/FUZZING.md.
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
SECONDS_EACH="${1:-30}"
shift || true
TARGETS=("$@")
[ "${#TARGETS[@]}" -gt 0 ] || TARGETS=(fuzz_glb fuzz_gltf fuzz_obj fuzz_ply fuzz_trc fuzz_landmarks fuzz_options fuzz_job_spec fuzz_components)
JOBS="$(nproc 2>/dev/null || echo 2)"

bash docker/install-deps.sh
cmake -S . -B build/fuzz -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" -DRIGPORT_FUZZ=ON -DRIGPORT_BUILD_TESTS=OFF -DRIGPORT_BUILD_BENCHMARKS=OFF > /dev/null
cmake --build build/fuzz -j "$JOBS" --target fuzz_targets rigport

# ---- seeds
SEEDS="$ROOT/build/fuzz/seeds"
rm -rf "$SEEDS"
for t in "${TARGETS[@]}"; do mkdir -p "$SEEDS/$t"; done
seed() { [ -d "$SEEDS/$1" ] && cp "$2" "$SEEDS/$1/" 2>/dev/null || true; }
GEN="$ROOT/build/fuzz/generated"
rm -rf "$GEN" && mkdir -p "$GEN"
build/fuzz/client/rigport -q demo --out "$GEN/demo" --inputs-only
build/fuzz/client/rigport -q generate-head -o "$GEN/head.glb" --landmarks "$GEN/head.landmarks.json" --seed 5
for f in "$GEN"/demo/*.glb "$GEN"/head.glb; do seed fuzz_glb "$f"; done
for f in "$GEN"/demo/*.json "$GEN"/head.landmarks.json; do seed fuzz_landmarks "$f"; done
# glTF JSON: the JSON chunk of each generated GLB.
python3 - "$GEN" "$SEEDS/fuzz_gltf" <<'PY'
import os, struct, sys
gen, out = sys.argv[1], sys.argv[2]
if os.path.isdir(out):
    for root, _, files in os.walk(gen):
        for name in files:
            if name.endswith(".glb"):
                data = open(os.path.join(root, name), "rb").read()
                length = struct.unpack_from("<I", data, 12)[0]
                open(os.path.join(out, name[:-4] + ".gltf"), "wb").write(data[20:20 + length])
PY
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nf 1 3 4\nf 1 4 2\nf 2 4 3\n' > "$GEN/tet.obj"
seed fuzz_obj "$GEN/tet.obj"
printf 'ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty int region\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1\n1 0 0 1\n0 1 0 2\n0 0 1 2\n3 0 1 2\n3 0 2 3\n' > "$GEN/tet.ply"
seed fuzz_ply "$GEN/tet.ply"
python3 - "$GEN/tet_binary.ply" <<'PY'
import struct, sys
head = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
body = b"".join(struct.pack("<6f", *v, 0, 0, 1) for v in [(0, 0, 0), (1, 0, 0), (0, 1, 0)]) + struct.pack("<B3i", 3, 0, 1, 2)
open(sys.argv[1], "wb").write(head + body)
PY
seed fuzz_ply "$GEN/tet_binary.ply"
printf 'PathFileType\t4\t(X/Y/Z)\tclip.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n30\t30\t3\t2\tmm\t30\t1\t3\nFrame#\tTime\tnose\t\t\tchin\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n1\t0\t0\t0\t0\t1\t1\t1\n2\t0.033\t0\t0.1\t0\t1\t\t1\n3\t0.066\t0\t0.2\t0\t1\t1.2\t1\n' > "$GEN/clip.trc"
seed fuzz_trc "$GEN/clip.trc"
echo '{"influences": 4, "adapt_deltas": "local", "exaggeration": 1.2, "correspondence": {"side_matching": true}}' > "$GEN/transfer.json"
echo '{"method": "hybrid", "kernel": "gaussian", "tolerance": 0.05, "stiffness": {"nose": 3}}' > "$GEN/retarget.json"
echo '{"nose": 2, "chin": 9}' > "$GEN/stiffness.json"
echo '{"correspondence": "fit", "max_influences": 4, "adaptation": "local", "strict": true}' > "$GEN/transfer_fit.json"
echo '{"alignment": "search", "units": "mm", "frame": "scan", "normal_matching": 0.03, "schedule": [{"stiffness": 10, "iterations": 3, "max_distance": 0.05, "point_share": 1}], "components": {"shapes": false}, "strict": true}' > "$GEN/fit.json"
for f in "$GEN"/transfer.json "$GEN"/transfer_fit.json "$GEN"/retarget.json "$GEN"/stiffness.json "$GEN"/fit.json; do seed fuzz_options "$f"; done
echo '{"kind": "transfer", "rig": "'"$(printf '%064d' 0)"'", "options": {"influences": 4}}' > "$GEN/spec_transfer.json"
echo '{"kind": "retarget", "options": {"method": "geodesic"}}' > "$GEN/spec_retarget.json"
echo '{"kind": "fit", "rig": "'"$(printf '%064d' 0)"'", "options": {"alignment": "landmarks"}}' > "$GEN/spec_fit.json"
for f in "$GEN"/spec_*.json; do seed fuzz_job_spec "$f"; done
# The components document's example (docs/COMPONENTS.md, its first json block;
# the pose JSON's example comes after it).
awk '/^```json$/ { n++; inside = (n == 1); next } /^```$/ { inside = 0 } inside' "$ROOT/docs/COMPONENTS.md" > "$GEN/components.json"
seed fuzz_components "$GEN/components.json"
SHARED="$ROOT/../shared/data"
if [ -d "$SHARED" ]; then
  while IFS= read -r f; do
    case "$f" in
      *.glb) seed fuzz_glb "$f" ;;
      *.obj) seed fuzz_obj "$f" ;;
      *.ply) seed fuzz_ply "$f" ;;
      *.trc) seed fuzz_trc "$f" ;;
      *landmarks*.json|*markers.json) seed fuzz_landmarks "$f" ;;
    esac
  done < <(find "$SHARED" -type f -size -1500k \( -name '*.glb' -o -name '*.obj' -o -name '*.ply' -o -name '*.trc' -o -name '*.json' \))
else
  echo "fuzz: ../shared/data absent; seeding from generated files only"
fi

# ---- runs
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:allocator_may_return_null=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
failed=()
for t in "${TARGETS[@]}"; do
  corpus="$ROOT/build/fuzz/corpus/$t"
  findings="$ROOT/build/fuzz/findings/$t"
  mkdir -p "$corpus" "$findings"
  log="$ROOT/build/fuzz/$t.log"
  if "build/fuzz/tests/fuzz/$t" "$corpus" "$SEEDS/$t" -max_total_time="$SECONDS_EACH" -timeout=60 -rss_limit_mb=2048 \
       -max_len=4194304 -artifact_prefix="$findings/" -print_final_stats=1 > "$log" 2>&1; then
    runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
    echo "fuzz: $t ok, ${runs:-?} executions in ${SECONDS_EACH} s, corpus $(ls "$corpus" | wc -l) inputs"
  else
    echo "fuzz: $t FOUND A PROBLEM (input in $findings, log $log):"
    grep -E "ERROR|SUMMARY|Test unit written" "$log" | head -5
    failed+=("$t")
  fi
done
[ "${#failed[@]}" -eq 0 ] || { echo "fuzz: findings in ${failed[*]}"; exit 1; }
