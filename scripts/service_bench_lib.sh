# Sourced by scripts/bench_service.sh and scripts/soak.sh: the load's inputs
# and a rigport-server on loopback with a fresh store.
#   rigport_bench_inputs OUT      sets INPUTS (ICT rig onto id_s02_remesh when
#                                 ../shared/data is present, else the demo's)
#   rigport_start_server OUT WORKERS CACHE_MB   sets PID, URL and CLIENT_TLS; stopped on exit
#                                 (RIGPORT_BENCH_TLS=1: HTTPS with a self-signed
#                                 certificate, CLIENT_TLS=(--ca-cert FILE))
BIN="${RIGPORT_BUILD:-build/release}"

rigport_bench_inputs() {
  local out="$1" data="$ROOT/../shared/data/ict"
  if [ -f "$data/source_face_skinned.glb" ]; then
    INPUTS=(--source "$data/source_face_skinned.glb" --source-landmarks "$data/source_face.landmarks.json"
            --target "$data/targets/id_s02_remesh.glb" --target-landmarks "$data/targets/id_s02_remesh.landmarks.json")
  else
    "$BIN/client/rigport" -q demo --out "$out/demo" --inputs-only
    INPUTS=(--source "$out/demo/source_rig.glb" --source-landmarks "$out/demo/source_rig.landmarks.json"
            --target "$out/demo/target_head.glb" --target-landmarks "$out/demo/target_head.landmarks.json")
  fi
}

rigport_start_server() {
  local out="$1" workers="$2" cache_mb="$3"
  local server_tls=()
  CLIENT_TLS=()
  if [ "${RIGPORT_BENCH_TLS:-0}" = 1 ]; then
    openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 -subj /CN=localhost \
      -addext subjectAltName=DNS:localhost,IP:127.0.0.1 -keyout "$out/tls.key" -out "$out/tls.crt" 2> /dev/null
    server_tls=(--tls-cert "$out/tls.crt" --tls-key "$out/tls.key")
    CLIENT_TLS=(--ca-cert "$out/tls.crt")
  fi
  "$BIN/server/rigport-server" --listen 127.0.0.1:0 --data-dir "$out/store" --no-auth --workers "$workers" \
    --cache-mb "$cache_mb" "${server_tls[@]}" > "$out/server.out" 2> "$out/server.log" &
  PID=$!
  trap 'kill -TERM $PID 2>/dev/null || true' EXIT
  for _ in $(seq 1 100); do grep -q "listening on" "$out/server.out" && break; sleep 0.1; done
  URL="$(sed -n 's/^listening on //p' "$out/server.out")"
}
