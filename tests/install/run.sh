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

# A program built against the installed prefix only: flags from its kinemesh.pc (static), no
# path into the source or build tree. An octahedron by hand: counts, and a Laplacian (CHOLMOD's
# side of the archive, so Libs.private is exercised).
PC=$(ls "$P"/lib*/pkgconfig/kinemesh.pc 2>/dev/null | head -n 1)
[ -n "$PC" ] || fail "kinemesh.pc not installed (expected PREFIX/lib/pkgconfig/kinemesh.pc)"
cat >"$WORK/octa.c" <<'EOC'
#include <kinemesh.h>

#include <math.h>
#include <stdio.h>

int main(void) {
  double V[] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
  int32_t F[] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  km_mesh m = {.V = V, .F = F, .n_vertices = 6, .n_faces = 8};
  km_mesh_info info;
  km_error err;
  if (km_mesh_info_compute(&m, &info, &err) != KM_OK) {
    printf("km_mesh_info_compute: %s\n", err.message);
    return 1;
  }
  km_sparse *L = NULL;
  if (km_cotmatrix(&m, &L, &err) != KM_OK) {
    printf("km_cotmatrix: %s\n", err.message);
    return 1;
  }
  double ones[6] = {1, 1, 1, 1, 1, 1}, r[6];
  km_sparse_mul(L, 1, ones, r);
  double rs = 0;
  for (int i = 0; i < 6; ++i)
    rs += fabs(r[i]);
  size_t nnz = km_sparse_nnz(L);
  km_sparse_free(&L);
  printf("kinemesh %s: %zu vertices, %zu faces, %zu edges, %zu boundary edges, %zu component, "
         "euler %lld; L %zu nonzeros, |L*1| %.1e\n",
         km_version(), info.vertices, info.faces, info.edges, info.boundary_edges,
         info.components, (long long)info.euler_characteristic, nnz, rs);
  return info.vertices == 6 && info.faces == 8 && info.edges == 12 && info.boundary_edges == 0 &&
                 info.components == 1 && info.euler_characteristic == 2 && nnz == 6 + 2 * 12 &&
                 rs < 1e-12
             ? 0
             : 1;
}
EOC
FLAGS=$(PKG_CONFIG_PATH=$(dirname "$PC") pkg-config --cflags --libs --static kinemesh) ||
  fail "pkg-config --cflags --libs --static kinemesh"
case $FLAGS in *"$P"*) ;; *) fail "kinemesh.pc does not point into the prefix: $FLAGS" ;; esac
(cd "$WORK" && cc -std=c11 octa.c $FLAGS -o octa) || fail "a program against the installed library does not build: cc octa.c $FLAGS"
"$WORK/octa" || fail "a program against the installed library gives wrong counts"
echo "ok   a program built with pkg-config --static kinemesh against the prefix runs"

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
