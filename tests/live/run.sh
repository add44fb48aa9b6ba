#!/usr/bin/env bash
# ctest driver for live mode: run.sh e2e|e2e_quantize|e2e_norig|e2e_nohandles|osc|garbage|vmc|camera|security KINEMESH WORKDIR
# (security: tests/security/run.sh, which names its script in KM_LIVE_SCRIPT)
# Generates a small character and take, starts `kinemesh live` on loopback with random free
# ports (retrying when a port is taken), runs the matching node script against it, stops the
# server with SIGTERM and checks it exits cleanly. A missing tool (chromium, oscsend: the set-up
# installs them) is a failure, not a skip.
set -uo pipefail
MODE=$1
BIN=$2
WORK=$3
HERE=$(cd "$(dirname "$0")" && pwd)
ROOT=$(cd "$HERE/../.." && pwd)
command -v node >/dev/null || { echo "FAIL: node not found (scripts/deps.sh installs it)"; exit 1; }
[ -d "$ROOT/web/node_modules/playwright-core" ] || { echo "FAIL: web/node_modules missing (run scripts/deps.sh)"; exit 1; }
if { [ "${MODE#e2e}" != "$MODE" ] || [ "$MODE" = camera ]; } && ! command -v chromium >/dev/null; then echo "FAIL: chromium not installed (scripts/deps.sh installs it)"; exit 1; fi
if [ "$MODE" = osc ] && ! command -v oscsend >/dev/null; then echo "FAIL: oscsend not installed (scripts/deps.sh installs liblo-tools)"; exit 1; fi
if [ "$MODE" = camera ] && [ ! -f "$ROOT/web/node_modules/@mediapipe/pose/pose.js" ]; then echo "FAIL: @mediapipe/pose missing (run scripts/deps.sh)"; exit 1; fi
BVH="$ROOT/../shared/data/bvh/cmu_131_01.bvh"
if [ "$MODE" = vmc ] && [ ! -f "$BVH" ]; then echo "SKIP: $BVH not found (../shared/data is absent)"; exit 77; fi
rm -rf "$WORK" && mkdir -p "$WORK"
"$BIN" gen character --vertices 3000 -o "$WORK/c.obj" >/dev/null 2>&1 || { echo "FAIL: gen character"; exit 1; }
"$BIN" gen motion --kind wave --frames 60 --character "$WORK/c.obj" -o "$WORK/t.json" >/dev/null 2>&1 || { echo "FAIL: gen motion"; exit 1; }
"$BIN" precompute "$WORK/c.obj" >/dev/null 2>&1 || { echo "FAIL: precompute"; exit 1; }

EXTRA=()
case $MODE in
  e2e) EXTRA=(--replay "$WORK/t.json" --no-autoplay) ;;
  e2e_quantize) EXTRA=(--replay "$WORK/t.json" --no-autoplay --quantize) ;;
  e2e_norig) # a scan's own colours (v x y z r g b): the page shows them where no handle is
    rm -f "$WORK/c.rig.json"
    awk '$1 == "v" { print $1, $2, $3, $4, 0.9, 0.4, 0.1; next } { print }' "$WORK/c.obj" >"$WORK/cc.obj" &&
      mv "$WORK/cc.obj" "$WORK/c.obj"
    EXTRA=(--no-autoplay) ;;
  e2e_nohandles) EXTRA=(--no-handles --replay "$WORK/t.json" --no-autoplay) ;;
  osc) EXTRA=(--record "$WORK/rec.json") ;;
  camera) EXTRA=(--record "$WORK/rec.json") ;;
  garbage) EXTRA=(--replay "$WORK/t.json" --no-autoplay --quantize) ;;
  security) EXTRA=(--replay "$WORK/t.json" --no-autoplay); chmod 600 "$WORK/c.rig.json" ;;
  vmc)
    # The character's rig rewritten for a humanoid (VMC) skeleton: Unity bone names.
    node -e '
      const fs = require("fs"), r = JSON.parse(fs.readFileSync(process.argv[1], "utf8"));
      const H = {Head: "Head", HandLeft: "LeftMiddleProximal", HandRight: "RightMiddleProximal",
                 FootLeft: "LeftToes", FootRight: "RightToes", HipCenter: "Hips",
                 ShoulderCenter: "Neck", ShoulderLeft: "LeftUpperArm", ElbowLeft: "LeftLowerArm",
                 WristLeft: "LeftHand", ShoulderRight: "RightUpperArm", ElbowRight: "RightLowerArm",
                 WristRight: "RightHand", HipLeft: "LeftUpperLeg", KneeLeft: "LeftLowerLeg",
                 AnkleLeft: "LeftFoot", HipRight: "RightUpperLeg", KneeRight: "RightLowerLeg",
                 AnkleRight: "RightFoot", Spine: "Spine"};
      const hn = (j) => { if (!H[j]) throw new Error("no humanoid name for " + j); return H[j]; };
      r.skeleton = "humanoid";
      if (r.relative_to) { r.relative_to = hn(r.relative_to); r.heading = [hn("HipLeft"), hn("HipRight")]; }
      for (const m of r.map) { if (m.bone) m.bone = m.bone.map(hn); else m.joint = hn(m.joint); }
      fs.writeFileSync(process.argv[2], JSON.stringify(r));' "$WORK/c.rig.json" "$WORK/h.rig.json" \
      || { echo "FAIL: humanoid rig"; exit 1; }
    EXTRA=(--rig "$WORK/h.rig.json") ;;
esac

PID=
for try in 1 2 3 4 5 6 7 8; do
  BASE=$((20000 + (RANDOM * 7 + $$ + try * 101) % 40000))
  HTTP=$BASE OSC=$((BASE + 1)) UDP=$((BASE + 2)) VMC=$((BASE + 3))
  VMC_OUT=()
  [ "$MODE" = vmc ] && VMC_OUT=(--vmc-out 127.0.0.1:$((BASE + 4)))
  "$BIN" live --mesh "$WORK/c.obj" --http $HTTP --osc $OSC --udp $UDP --vmc $VMC "${VMC_OUT[@]}" "${EXTRA[@]}" \
    >"$WORK/server.out" 2>"$WORK/server.err" &
  PID=$!
  for i in $(seq 1 100); do
    grep -q "open http" "$WORK/server.out" 2>/dev/null && break
    kill -0 $PID 2>/dev/null || break
    sleep 0.1
  done
  if kill -0 $PID 2>/dev/null && grep -q "open http" "$WORK/server.out"; then break; fi
  wait $PID 2>/dev/null
  PID=
  grep -q "cannot" "$WORK/server.err" || { echo "FAIL: server did not start"; cat "$WORK/server.err"; exit 1; }
done
[ -n "$PID" ] || { echo "FAIL: no free ports found"; exit 1; }
cleanup() { [ -n "$PID" ] && kill -9 $PID 2>/dev/null; }
trap cleanup EXIT

# The per-run secret from the printed URL (issue 18): the scripts send it like the page does.
KM_LIVE_TOKEN=$(grep -o 'token=[A-Za-z0-9_-]*' "$WORK/server.out" | head -1 | cut -d= -f2)
[ -n "$KM_LIVE_TOKEN" ] || { echo "FAIL: no ?token= in the printed URL"; cat "$WORK/server.out"; exit 1; }
export KM_LIVE_TOKEN
SCRIPT=${KM_LIVE_SCRIPT:-$HERE/${MODE%_quantize}.mjs}
# The camera runs MediaPipe Pose on software WebGL: slow on a loaded machine, more time.
TMO=90
[ "$MODE" = camera ] && TMO=340
KM_BIN="$BIN" KM_VMC=$VMC KM_VMC_OUT=$((BASE + 4)) KM_BVH="$BVH" timeout $TMO node "$SCRIPT" "$HTTP" "$OSC" "$UDP" "$WORK"
rc=$?
kill -0 $PID 2>/dev/null || { echo "FAIL: the server died"; cat "$WORK/server.err"; exit 1; }
kill -TERM $PID
for i in $(seq 1 100); do kill -0 $PID 2>/dev/null || break; sleep 0.1; done
wait $PID
src=$?
PID=
tail -3 "$WORK/server.err"
[ $src -eq 0 ] || { echo "FAIL: server exit status $src after SIGTERM"; cat "$WORK/server.err"; exit 1; }
[ $rc -eq 0 ] || exit $rc
if [ "$MODE" = osc ]; then
  # The recorded session replays offline.
  [ -s "$WORK/rec.json" ] || { echo "FAIL: --record wrote nothing"; exit 1; }
  "$BIN" animate --mesh "$WORK/c.obj" --motion "$WORK/rec.json" -o "$WORK/rec.pc2" 2>"$WORK/animate.err" \
    || { echo "FAIL: animate on the recorded take"; cat "$WORK/animate.err"; exit 1; }
  echo "recorded take animates offline: ok"
fi
if [ "$MODE" = camera ]; then
  # What the server received from the page's camera, against the clip, and animated.
  "$BIN" animate --mesh "$WORK/c.obj" --motion "$WORK/rec.json" -o "$WORK/rec.pc2" 2>"$WORK/animate.err" \
    || { echo "FAIL: animate on the recorded take"; cat "$WORK/animate.err"; exit 1; }
  node "$HERE/camera_check.mjs" "$WORK" || exit 1
fi
echo "live_$MODE: passed"
