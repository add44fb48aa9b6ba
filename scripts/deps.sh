#!/usr/bin/env bash
# Installs the Debian packages kinemesh builds against, skipping those already present.
# Called by `make demo` / `make test`; safe to run repeatedly. clang and libclang-rt-dev (its
# sanitizer and libFuzzer runtimes) are for the fuzz test only (fuzz/run.sh skips without them).
# `scripts/deps.sh --test` (what `make test` runs) also installs TEST_PKGS: packages only a test
# needs and `make demo` does not (Blender, ~720 MB, for the ctest blender_import; its glTF
# importer needs numpy, which Debian's blender package does not pull in; gltfpack packs a mesh
# for test_gltf_meshopt, which skips without it; draco's draco_transcoder compresses glTF files
# with Draco for test_gltf_draco, whose transcoder part skips without it, saying so).
set -euo pipefail
TEST_PKGS=(blender python3-numpy gltfpack draco)
PKGS=(build-essential cmake pkg-config
      libsuitesparse-dev libarpack2-dev liblapacke-dev libopenblas-dev
      libembree-dev libcjson-dev libsvm-dev liblbfgs-dev libmeshoptimizer-dev gltfpack libdraco-dev
      liblo-dev liblo-tools libwebsockets-dev gnuplot-nox
      nodejs npm chromium
      libopenmpi-dev openmpi-bin
      clang libclang-rt-dev)
if [ "${1:-}" = --test ]; then PKGS+=("${TEST_PKGS[@]}"); fi
missing=()
for p in "${PKGS[@]}"; do
  [[ "$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null)" == *"install ok installed"* ]] || missing+=("$p")
done
# Debian's nodejs/npm are skipped when another node installation is already on PATH.
if command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1; then
  keep=()
  for p in "${missing[@]}"; do [ "$p" = nodejs ] || [ "$p" = npm ] || keep+=("$p"); done
  missing=("${keep[@]}")
fi
if [ ${#missing[@]} -gt 0 ]; then
  echo "kinemesh: installing missing packages: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# npm packages used by the test suite (Khronos glTF validator), pinned by package-lock.json.
here=$(cd "$(dirname "$0")/.." && pwd)
if [ ! -d "$here/tests/gltf/node_modules/gltf-validator" ]; then
  echo "kinemesh: installing npm packages for tests/gltf"
  (cd "$here/tests/gltf" && npm ci --no-audit --no-fund --loglevel=error)
fi

# Live mode page: three.js and @mediapipe/pose (the Camera button: its JS, WASM and model
# weights; all copied beside the binary by the build, served by kinemesh, no CDN) and
# playwright-core (drives Debian's chromium in the end-to-end tests; no browser download),
# pinned by package-lock.json.
if [ ! -d "$here/web/node_modules/three" ] || [ ! -d "$here/web/node_modules/playwright-core" ] ||
   [ ! -f "$here/web/node_modules/@mediapipe/pose/pose.js" ]; then
  echo "kinemesh: installing npm packages for web/"
  (cd "$here/web" && npm ci --no-audit --no-fund --loglevel=error)
fi
