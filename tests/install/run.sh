#!/usr/bin/env bash
# ctest driver: `cmake --install` into a scratch prefix, then the installed binary serves the
# live page from PREFIX/share/kinemesh/web (no web/ beside it), and the header compiles alone.
set -uo pipefail
BUILD=$1
WORK=$2
rm -rf "$WORK" && mkdir -p "$WORK"
P=$WORK/prefix
fail() { echo "FAIL: $*"; exit 1; }
cmake --install "$BUILD" --prefix "$P" >"$WORK/install.log" 2>&1 || { cat "$WORK/install.log"; fail "cmake --install"; }
for f in bin/kinemesh include/kinemesh.h share/kinemesh/web/index.html share/kinemesh/web/live.js \
  share/kinemesh/web/three.module.js; do
  [ -f "$P/$f" ] || fail "$f not installed"
done
ls "$P"/lib*/libkinemesh.a >/dev/null 2>&1 || fail "libkinemesh.a not installed"
[ -d "$P/bin/web" ] && fail "the page went beside the binary; expected share/kinemesh/web"
echo "ok   installed: bin/kinemesh, include/kinemesh.h, lib/libkinemesh.a, share/kinemesh/web"

printf '#include <kinemesh.h>\nint main(void) { km_mesh m = {0}; (void)m; return 0; }\n' >"$WORK/use.c"
cc -std=c11 -fsyntax-only -I"$P/include" "$WORK/use.c" || fail "the installed header does not compile on its own"
echo "ok   the installed header compiles alone"

K=$P/bin/kinemesh
"$K" gen character --vertices 2000 -o "$WORK/c.obj" >/dev/null 2>&1 || fail "installed kinemesh gen character"
"$K" precompute "$WORK/c.obj" >/dev/null 2>&1 || fail "installed kinemesh precompute"
PID=
for try in 1 2 3 4 5 6; do
  HTTP=$((20000 + (RANDOM * 7 + $$ + try * 131) % 40000))
  "$K" live --mesh "$WORK/c.obj" --http $HTTP --osc 0 --udp 0 >"$WORK/server.out" 2>"$WORK/server.err" &
  PID=$!
  for i in $(seq 1 100); do
    grep -q "open http" "$WORK/server.out" 2>/dev/null && break
    kill -0 $PID 2>/dev/null || break
    sleep 0.1
  done
  grep -q "open http" "$WORK/server.out" 2>/dev/null && break
  kill $PID 2>/dev/null; wait $PID 2>/dev/null; PID=
done
[ -n "$PID" ] || { cat "$WORK/server.err"; fail "installed kinemesh live did not start"; }
node -e "
(async () => {
  const u = 'http://127.0.0.1:$HTTP/';
  const page = await (await fetch(u)).text();
  const js = await fetch(u + 'three.module.js');
  if (!page.includes('live.js') || js.status !== 200) { console.log('FAIL: page ' + page.length + ' bytes, three.js ' + js.status); process.exit(1); }
  console.log('ok   the installed server serves its page (' + page.length + ' bytes) and three.js');
})().catch((e) => { console.log('FAIL: ' + e); process.exit(1); });
"
rc=$?
kill $PID 2>/dev/null
wait $PID 2>/dev/null
exit $rc
