#!/usr/bin/env bash
# The main job on the built-in default: a procedural character and a generated kung-fu take,
# animated and written to out/demo.glb. Called by `make demo` after the build.
set -euo pipefail
BIN=${1:-build/kinemesh}
OUT=out
mkdir -p "$OUT"
"$BIN" gen character --vertices 20000 -o "$OUT/character.obj"
"$BIN" gen motion --kind kungfu --frames 150 --character "$OUT/character.obj" -o "$OUT/kungfu.json"
"$BIN" animate --mesh "$OUT/character.obj" --motion "$OUT/kungfu.json" -o "$OUT/demo.glb"
"$BIN" info "$OUT/demo.glb"
echo
echo "Result: $(pwd)/$OUT/demo.glb  (glTF 2.0 binary, morph-target animation;"
echo "        open it in Blender: File > Import > glTF 2.0, or any glTF viewer)"
