#!/usr/bin/env bash
# ctest (issue 16): three.js in headless chromium plays kinemesh's exports — per-frame morphs
# (exact within 0.01 mm), a skinned and a PCA-morph export (within their reported max error) — at frames
# 0, the middle and the last, against the exact frames (.pc2) of the same LBS playback, and pose's
# skeleton export (exact within 0.01 mm); the same four kinds with --compress (MeshoptDecoder);
# and the skeleton export of the character with a ground quad bound to the armature's root.
# Skipped (77) with a message when node, chromium or web/node_modules is missing.
set -euo pipefail
BIN=$1
WORK=$2
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
command -v node >/dev/null || { echo "SKIP: node not found (scripts/deps.sh installs it)"; exit 77; }
[ -x "${CHROMIUM:-/usr/bin/chromium}" ] || { echo "SKIP: chromium not installed (scripts/deps.sh installs it)"; exit 77; }
[ -d "$ROOT/web/node_modules/three" ] && [ -d "$ROOT/web/node_modules/playwright-core" ] ||
  { echo "SKIP: web/node_modules missing (run scripts/deps.sh)"; exit 77; }
rm -rf "$WORK" && mkdir -p "$WORK"
"$BIN" gen character --vertices 2000 -o "$WORK/c.obj" 2>/dev/null
"$BIN" gen motion --kind wave --frames 24 --character "$WORK/c.obj" -o "$WORK/t.json" 2>/dev/null
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" -o "$WORK/exact.pc2" 2>/dev/null
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" -o "$WORK/morphs.glb" 2>/dev/null
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --export skin:16 -o "$WORK/skin.glb" 2>/dev/null
node "$HERE/three_check.mjs" "$WORK/morphs.glb" "$WORK/exact.pc2" 0.01
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --export morphs:6 -o "$WORK/pca.glb" 2>/dev/null
node "$HERE/three_check.mjs" "$WORK/skin.glb" "$WORK/exact.pc2" auto
node "$HERE/three_check.mjs" "$WORK/pca.glb" "$WORK/exact.pc2" auto
# --compress: decoded by three.js's MeshoptDecoder, within the error the file reports (which
# includes the quantisation).
# pose --export skeleton: the rig's own bones, exact (within 0.01 mm)
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/skel.glb" 2>/dev/null
node "$HERE/three_check.mjs" "$WORK/skel.glb" "$WORK/exact.pc2" 0.01
for k in morphs:all skin:16 morphs:6 skeleton; do
  "$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --export $k --compress -o "$WORK/z.glb" 2>/dev/null
  node "$HERE/three_check.mjs" "$WORK/z.glb" "$WORK/exact.pc2" auto
done
# a ground quad under the feet, which rig leaves out of the skin: bound to the armature's root,
# it stays in three.js as in pose's frames (plain and compressed)
awk -f "$HERE/../data/ground_quad.awk" "$WORK/c.obj" >"$WORK/cg.obj"
"$BIN" rig "$WORK/cg.obj" -o "$WORK/cg.rig.json" >/dev/null 2>&1
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" -o "$WORK/ground.pc2" 2>/dev/null
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/ground.glb" 2>/dev/null
node "$HERE/three_check.mjs" "$WORK/ground.glb" "$WORK/ground.pc2" 0.01
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" --export skeleton --compress -o "$WORK/z.glb" 2>/dev/null
node "$HERE/three_check.mjs" "$WORK/z.glb" "$WORK/ground.pc2" auto
echo "gltf_three: 10 passed, 0 failed"
