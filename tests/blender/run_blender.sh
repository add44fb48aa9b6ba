#!/usr/bin/env bash
# ctest blender (issue 16): Debian's Blender, headless, imports each glTF export kind of a short
# puppetry run (kinemesh gen + animate: per-frame morphs, compact morphs:K, a skin, and a
# compressed skin, which Blender 3.4 refuses: see blender_check.py), and pose's skeleton export
# (the rig's own bones against pose's exact frames; and with a ground quad bound to the
# armature's root), with its own
# glTF importer and, at frames 0, the middle and the last, the evaluated vertex positions match
# the exact frames (.pc2 of the same run) within the file's reported error (skin, morphs:K; plus
# 0.1 mm for float32) or 0.1 mm (morphs:all). See blender_check.py. And `animate --keep-frame`'s
# point cache on a z-up copy, played by Blender's Mesh Cache modifier on that file imported as
# stored, lines up with it (blender_pc2_frame.py). And Blender's own STL files (ASCII and
# binary) of the character, read back by kinemesh, and kinemesh's STL imported by Blender
# (blender_stl.py).
# Skipped (77) with a message when blender (or its numpy) is missing, except in CI (CI=true),
# where scripts/deps.sh --test installs it and a missing blender fails.
set -euo pipefail
BIN=$1
WORK=$2
HERE=$(cd "$(dirname "$0")" && pwd)
# shellcheck source-path=SCRIPTDIR source=common.sh
. "$HERE/common.sh"
rm -rf "$WORK" && mkdir -p "$WORK"
"$BIN" gen character --vertices 2000 -o "$WORK/c.obj" 2>/dev/null
"$BIN" gen motion --kind kungfu --frames 24 --character "$WORK/c.obj" -o "$WORK/t.json" 2>/dev/null
run() { "$BIN" animate --mesh "$WORK/c.obj" --motion "$WORK/t.json" "$@" >/dev/null 2>&1; }
run -o "$WORK/exact.pc2"
run -o "$WORK/morphs.glb"
run --export morphs:6 -o "$WORK/pca.glb"
run --export skin:16 -o "$WORK/skin.glb"
run --export skin:16 --compress -o "$WORK/skin_z.glb"
# pose --export skeleton: the rig's own skeleton and weights with each frame's bone transforms
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" -o "$WORK/pose_exact.pc2" >/dev/null 2>&1
"$BIN" pose --mesh "$WORK/c.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/skel.glb" >/dev/null 2>&1
rc=0
check() {
  # --python-exit-code: an exception in the script fails Blender (it exits 0 otherwise);
  # the script's own verdict comes through sys.exit.
  local out brc=0 try
  for try in 1 2; do
    brc=0
    out=$("$BLENDER" -b --factory-startup --python-exit-code 2 --python "$HERE/blender_check.py" \
      -- "$@" 2>&1) || brc=$?
    # Blender killed by a signal (exit status > 128) is Blender's crash, not a verdict: a CI run
    # under load once ended a passing check that way; one more run decides
    [ $brc -gt 128 ] && [ $try -eq 1 ] && echo "note: Blender exited with status $brc; running it again" && continue
    break
  done
  echo "$out" | grep -E '^(ok|FAIL|note|/)' || true
  # a here-string, not `echo | grep -q`: under pipefail that fails when grep exits at its first
  # match before echo has written all of Blender's output (SIGPIPE)
  if [ $brc -ne 0 ] || ! grep -q '^ok:' <<<"$out"; then
    [ $brc -eq 1 ] || { echo "$out" | tail -20; echo "Blender's exit status: $brc"; }
    rc=1
  fi
}
check "$WORK/morphs.glb" "$WORK/exact.pc2" "$WORK/c.obj" 0.1
check "$WORK/pca.glb" "$WORK/exact.pc2" "$WORK/c.obj" auto
check "$WORK/skin.glb" "$WORK/exact.pc2" "$WORK/c.obj" auto
check "$WORK/skel.glb" "$WORK/pose_exact.pc2" "$WORK/c.obj" auto
# with a ground quad under its feet: rig leaves the quad out of the skin, the export binds it to
# the armature's root (a joint no channel moves), and Blender keeps it where pose does
awk -f "$HERE/../data/ground_quad.awk" "$WORK/c.obj" >"$WORK/cg.obj"
"$BIN" rig "$WORK/cg.obj" -o "$WORK/cg.rig.json" >/dev/null 2>&1
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" -o "$WORK/ground_exact.pc2" >/dev/null 2>&1
"$BIN" pose --mesh "$WORK/cg.obj" --motion "$WORK/t.json" --export skeleton -o "$WORK/ground_skel.glb" >/dev/null 2>&1
check "$WORK/ground_skel.glb" "$WORK/ground_exact.pc2" "$WORK/cg.obj" auto
# --compress: Blender 3.4 refuses EXT_meshopt_compression (passes as documented; a Blender that
# decodes it must play it within the reported error)
check "$WORK/skin_z.glb" "$WORK/exact.pc2" "$WORK/c.obj" auto compressed
# animate --keep-frame (issue 11): the character stored z up (Blender's axes), its point cache
# played by Blender's Mesh Cache modifier on the file imported as it is stores lines up with
# it (blender_pc2_frame.py); the same cache in kinemesh's frame (y up) does not, so the check
# can fail
awk '/^v /{printf "v %s %.9g %s\n", $2, -$4, $3; next} {print}' "$WORK/c.obj" >"$WORK/zup.obj"
"$BIN" animate --mesh "$WORK/zup.obj" --motion "$WORK/t.json" --up +z --forward -y --keep-frame \
  -o "$WORK/keep.pc2" >/dev/null 2>&1
"$BIN" animate --mesh "$WORK/zup.obj" --motion "$WORK/t.json" --up +z --forward -y \
  -o "$WORK/plain.pc2" >/dev/null 2>&1
frame_check() { # CACHE WANT(0: lines up, 1: off)
  local out brc=0
  out=$("$BLENDER" -b --factory-startup --python-exit-code 2 --python "$HERE/blender_pc2_frame.py" \
    -- "$WORK/zup.obj" "$1" 20 2>&1) || brc=$?
  echo "$out" | grep -E '^(ok|FAIL|note)' || true
  if [ $brc -ne "$2" ]; then
    echo "$1: Blender's exit status $brc, expected $2"
    [ $brc -eq 2 ] && echo "$out" | tail -20
    rc=1
  fi
}
frame_check "$WORK/keep.pc2" 0
frame_check "$WORK/plain.pc2" 1
# STL (issue 11, any triangle mesh): Blender's own STL exporter writes the character as ASCII and
# binary STL; kinemesh converts each to OBJ and must weld it back to the original's vertex count
# with every face's corners where the original has them; and Blender's STL importer reads
# kinemesh's own STL of it back the same way (blender_stl.py)
stl() { # ARGS...: one blender_stl.py run, its verdict kept
  local out brc=0
  out=$("$BLENDER" -b --factory-startup --python-exit-code 2 --python "$HERE/blender_stl.py" \
    -- "$@" 2>&1) || brc=$?
  echo "$out" | grep -E '^(ok|FAIL)' || true
  if [ $brc -ne 0 ]; then
    [ $brc -eq 1 ] || echo "$out" | tail -20
    rc=1
  fi
}
stl export "$WORK/c.obj" "$WORK/c_ascii.stl" "$WORK/c_bin.stl"
for k in ascii bin; do
  if "$BIN" convert "$WORK/c_$k.stl" "$WORK/c_$k.obj" >/dev/null; then
    stl check "$WORK/c.obj" "$WORK/c_$k.obj"
  else
    echo "FAIL: kinemesh convert could not read Blender's $k STL" && rc=1
  fi
done
# and kinemesh's own (binary) STL imported by Blender's STL importer
if "$BIN" convert "$WORK/c.obj" "$WORK/c_km.stl" >/dev/null; then
  stl import "$WORK/c.obj" "$WORK/c_km.stl"
else
  echo "FAIL: kinemesh convert could not write an STL" && rc=1
fi
[ $rc -eq 0 ] && echo "blender: 5 exports, the z-up point cache and STL both ways passed" || echo "blender: FAILED"
exit $rc
