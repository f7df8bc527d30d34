#!/usr/bin/env bash
# Installs everything rigport needs to build, test and run, from Debian 12 packages
# and the npm registry. Idempotent: re-running skips what is already present.
# Used by the README Quick start, .ci/run and the Dockerfile.
set -euo pipefail

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

PACKAGES=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  libeigen3-dev libnanoflann-dev libcpp-httplib-dev nlohmann-json3-dev
  libtinygltf-dev libspdlog-dev libfmt-dev libcli11-dev libsqlite3-dev libssl-dev
  openssl   # self-signed certificates for the TLS tests and RIGPORT_BENCH_TLS
  libtinyobjloader-dev libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev   # libFuzzer (scripts/fuzz.sh)
  postgresql libpq-dev   # PostgreSQL server for the tests (scripts/postgres.sh), libpq client library
)
# Node.js and npm run the glTF validator; any install that provides the commands
# will do (some images ship a nodejs build that bundles npm and conflicts with
# Debian's npm package).
command -v node >/dev/null 2>&1 || PACKAGES+=(nodejs)
command -v npm >/dev/null 2>&1 || PACKAGES+=(npm)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Khronos glTF validator, used by the tests on every GLB the project writes.
# Installed into a project-local prefix so no global npm state is needed.
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VALIDATOR_DIR="${RIGPORT_TOOLS_DIR:-$ROOT/.tools}"
if [ ! -f "$VALIDATOR_DIR/node_modules/gltf-validator/package.json" ]; then
  echo "install-deps: installing gltf-validator into $VALIDATOR_DIR"
  mkdir -p "$VALIDATOR_DIR"
  npm install --silent --no-audit --no-fund --prefix "$VALIDATOR_DIR" gltf-validator@2.0.0-dev.3.10
fi
# OpenAPI 3 schema validator, used by the tests on api/openapi.json.
if [ ! -f "$VALIDATOR_DIR/node_modules/@seriousme/openapi-schema-validator/package.json" ]; then
  echo "install-deps: installing @seriousme/openapi-schema-validator into $VALIDATOR_DIR"
  mkdir -p "$VALIDATOR_DIR"
  npm install --silent --no-audit --no-fund --prefix "$VALIDATOR_DIR" @seriousme/openapi-schema-validator@2.11.0
fi
echo "install-deps: ok"
