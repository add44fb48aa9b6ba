#!/usr/bin/env bash
# ctest blender_seams (issue 11): a mesh as Blender exports it once it is textured, split at
# its texture seams, goes through kinemesh rig + animate with every seam shut and its texture
# coordinates kept (blender_seams.py says how). Debian's Blender unwraps a generated character
# (Smart UV Project) and exports a .glb; kinemesh rigs it (welded at its seams), animates it to
# a point cache and a .glb; Blender checks both.
# Skipped (77) with a message when blender (or its numpy) is missing, except in CI (CI=true),
# where scripts/deps.sh --test installs it and a missing blender fails.
set -euo pipefail
BIN=$1
WORK=$2
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source-path=SCRIPTDIR source=common.sh
. "$HERE/common.sh"
rm -rf "$WORK" && mkdir -p "$WORK"
blend() { # runs blender_seams.py with the arguments; prints its verdict lines
  local out brc=0
  out=$("$BLENDER" -b --factory-startup --python-exit-code 2 --python "$HERE/blender_seams.py" \
    -- "$@" 2>&1) || brc=$?
  echo "$out" | grep -E '^(ok|FAIL|note)' || true
  if [ $brc -ne 0 ] || ! grep -q '^ok:' <<<"$out"; then
    [ $brc -eq 1 ] || { echo "$out" | tail -20; echo "Blender's exit status: $brc"; }
    echo "blender_seams: FAILED"
    exit 1
  fi
}
"$BIN" gen character --vertices 3000 -o "$WORK/c.obj" 2>/dev/null
"$BIN" gen motion --kind kungfu --frames 24 --character "$WORK/c.obj" -o "$WORK/t.json" 2>/dev/null
blend export "$WORK/c.obj" "$WORK/c_uv.glb"
info=$("$BIN" info "$WORK/c_uv.glb" --json)
echo "$info" | grep -E '"(components|seam_vertices)"' | tr -d ' \n'; echo
"$BIN" rig "$WORK/c_uv.glb" -o "$WORK/c_uv.rig.json" >"$WORK/rig.log" 2>&1 ||
  { cat "$WORK/rig.log"; echo "blender_seams: rig FAILED"; exit 1; }
for out in anim.pc2 anim.glb "skin.glb --export skin:16"; do
  # shellcheck disable=SC2086 # the export option is meant to split
  "$BIN" animate --mesh "$WORK/c_uv.glb" --rig "$WORK/c_uv.rig.json" --motion "$WORK/t.json" \
    -o "$WORK/"$out >"$WORK/animate.log" 2>&1 ||
    { cat "$WORK/animate.log"; echo "blender_seams: animate FAILED"; exit 1; }
done
blend check "$WORK/c_uv.glb" "$WORK/anim.pc2" "$WORK/anim.glb" "$WORK/skin.glb"
# OBJ outputs carry the material too: convert's .mtl beside the OBJ, a frame folder's
# materials.mtl, each with the texture image, as Blender's OBJ importer reads them
"$BIN" convert "$WORK/c_uv.glb" "$WORK/conv/c_uv.obj" >"$WORK/convert.log" 2>&1 ||
  { cat "$WORK/convert.log"; echo "blender_seams: convert FAILED"; exit 1; }
"$BIN" animate --mesh "$WORK/c_uv.glb" --rig "$WORK/c_uv.rig.json" --motion "$WORK/t.json" \
  -o "$WORK/frames" >"$WORK/animate.log" 2>&1 ||
  { cat "$WORK/animate.log"; echo "blender_seams: animate FAILED"; exit 1; }
blend objcheck "$WORK/c_uv.glb" "$WORK/conv/c_uv.obj" "$WORK/frames/frame_000000.obj" \
  "$WORK/frames/frame_000023.obj"
# a scan's vertex colours (v x y z r g b) through convert (PLY), animate (.glb) and a PLY frame
# folder, as Blender's importers read them
awk '$1 == "v" { t = $3 / 1.8; t = t < 0 ? 0 : t > 1 ? 1 : t; printf "v %s %s %s %.4f 0.5 %.4f\n", $2, $3, $4, t, 1 - t; next } { print }' \
  "$WORK/c.obj" >"$WORK/cc.obj"
"$BIN" convert "$WORK/cc.obj" "$WORK/cc.ply" >"$WORK/convert.log" 2>&1 ||
  { cat "$WORK/convert.log"; echo "blender_seams: convert FAILED"; exit 1; }
for out in cc.glb "cc_frames --frame-format ply"; do
  # shellcheck disable=SC2086 # the frame format option is meant to split
  "$BIN" animate --mesh "$WORK/cc.obj" --rig "$WORK/c.rig.json" --motion "$WORK/t.json" \
    -o "$WORK/"$out >"$WORK/animate.log" 2>&1 ||
    { cat "$WORK/animate.log"; echo "blender_seams: animate FAILED"; exit 1; }
done
blend colors "$WORK/cc.obj" "$WORK/cc.ply" "$WORK/cc.glb" "$WORK/cc_frames/frame_000010.ply"
# the outputs with the source's material and texture are valid glTF (the Khronos validator)
VALIDATE=$HERE/../gltf/validate.mjs
if command -v node >/dev/null && [ -d "$HERE/../gltf/node_modules/gltf-validator" ]; then
  for f in anim skin; do
    # a normal map and no TANGENT, as intended (validate.mjs says why)
    node "$VALIDATE" --allow MESH_PRIMITIVE_GENERATED_TANGENT_SPACE "$WORK/$f.glb" \
      >"$WORK/$f.valid.txt" 2>&1 || true
    grep -q ': 0 errors, 0 warnings' "$WORK/$f.valid.txt" ||
      { cat "$WORK/$f.valid.txt"; echo "blender_seams: $f.glb is not valid glTF"; exit 1; }
  done
  echo "validator: anim.glb and skin.glb with the texture and normal map, 0 errors, 0 warnings"
elif [ "${CI:-}" = true ]; then
  echo "FAIL: node or the glTF validator is missing (scripts/deps.sh installs them)"
  exit 1
else
  echo "note: node or the glTF validator is missing: the outputs' validity is not checked"
fi
# A game character as Blender writes it: Mixamo-named armature, Blender's bone-heat weights,
# unwrapped and exported skinned. With no rig given it is its own template: pose and animate
# use its skin, reconstruct fits it to a capture of a stockier body; every output keeps the
# seams shut, and reconstruct's points land on it.
blend export-skinned "$WORK/c.obj" "$WORK/c.rig.json" "$WORK/g.glb"
run() { # LOG CMD...: runs a kinemesh command, its output to LOG, failing the test on error
  local log=$1
  shift
  "$BIN" "$@" >"$WORK/$log" 2>&1 || { cat "$WORK/$log"; echo "blender_seams: $* FAILED"; exit 1; }
}
run pose.log pose --mesh "$WORK/g.glb" --motion "$WORK/t.json" -o "$WORK/g_pose.pc2"
grep -q "HipCenter <- mixamorig:Hips" "$WORK/pose.log" ||
  { cat "$WORK/pose.log"; echo "blender_seams: pose did not map the Mixamo skeleton"; exit 1; }
run animate.log animate --mesh "$WORK/g.glb" --motion "$WORK/t.json" -o "$WORK/g_anim.pc2"
run subject.log gen character --vertices 4000 --shape stocky -o "$WORK/s.obj"
run capture.log gen motion --kind kungfu --frames 10 --character "$WORK/s.obj" -o "$WORK/s.json"
run capture.log gen capture --character "$WORK/s.obj" --motion "$WORK/s.json" -o "$WORK/cap"
run recon.log reconstruct --template "$WORK/g.glb" --clouds "$WORK/cap" -o "$WORK/g_rec.glb" \
  --report "$WORK/g_rec.json"
grep 'kinemesh reconstruct:' "$WORK/recon.log"
mean=$(sed -n 's/.*mean point error \([0-9.]*\) mm.*/\1/p' "$WORK/recon.log")
awk -v m="$mean" 'BEGIN { exit !(m != "" && m < 3) }' ||
  { echo "blender_seams: reconstruct's mean point error '$mean' mm, expected < 3"; exit 1; }
blend gaps "$WORK/g.glb" "$WORK/g_pose.pc2" "$WORK/g_anim.pc2" "$WORK/g_rec.glb"
echo "blender_seams: passed"
