#!/usr/bin/env bash
# scripts/check_layers.sh must catch what it promises to: plants one violation at a time in a
# copy of the tree (src/, include/, scripts/) and expects exit status 1 with a line naming the
# planted file; the unplanted copy must pass.
#
#   tests/layers/planted.sh [WORK_DIR]
set -uo pipefail
SRC=$(cd "$(dirname "$0")/../.." && pwd)
WORK=${1:-$(mktemp -d)}
mkdir -p "$WORK"
WORK=$(cd "$WORK" && pwd)
fails=0
bad() { echo "FAIL: $*"; fails=$((fails + 1)); }

fresh() { # a clean copy of the tree in $WORK/tree
  rm -rf "$WORK/tree"
  mkdir -p "$WORK/tree"
  cp -r "$SRC/src" "$SRC/include" "$SRC/scripts" "$WORK/tree/"
}

# expect_fail NAME FILE [check_layers args...]: exit 1 and FILE named in a violation line.
# grep reads a here-string, not a pipe: under pipefail, `printf ... | grep -q` fails whenever
# grep exits at its match before printf has written everything (SIGPIPE; a CI run under load
# reported "no violation names libplanted.a" beside the very line naming it).
expect_fail() {
  local name=$1 file=$2
  shift 2
  local out rc
  out=$(bash "$WORK/tree/scripts/check_layers.sh" --root "$WORK/tree" "$@" 2>&1)
  rc=$?
  if [ $rc -ne 1 ]; then
    bad "$name: check_layers exited $rc, expected 1"
    printf '%s\n' "$out" | head -5
  elif ! grep -q "^layers: .*$file" <<<"$out"; then
    bad "$name: no violation names $file"
    printf '%s\n' "$out" | head -5
  else
    echo "ok: $name ($(printf '%s\n' "$out" | grep -m1 "$file"))"
  fi
}

# 0. the unplanted copy passes
fresh
out=$(bash "$WORK/tree/scripts/check_layers.sh" --root "$WORK/tree" 2>&1)
rc=$?
if [ $rc -ne 0 ]; then
  bad "unplanted copy: exit $rc, expected 0"
  printf '%s\n' "$out" | head -20
else
  echo "ok: unplanted copy passes"
fi

# 1. a lower module includes a higher one: mesh including recon
fresh
echo '#include "recon/recon.h"' >>"$WORK/tree/src/mesh/normals.c"
expect_fail "mesh includes recon/recon.h" "src/mesh/normals.c"

# 2. a private header of another module: recon including transfer/pose.h
fresh
f=$(ls "$WORK"/tree/src/recon/*.c | head -n 1)
echo '#include "transfer/pose.h"' >>"$f"
expect_fail "recon includes the private transfer/pose.h" "src/recon/$(basename "$f")"

# 2b. a private header of a module it does require: recon including mesh/mesh_args.h
fresh
echo '#include "mesh/mesh_args.h"' >>"$f"
expect_fail "recon includes the private mesh/mesh_args.h" "src/recon/$(basename "$f")"
out=$(bash "$WORK/tree/scripts/check_layers.sh" --root "$WORK/tree" 2>&1)
if ! grep -q "private header of module mesh" <<<"$out"; then
  bad "recon includes mesh/mesh_args.h: not reported as a private header"
fi

# 3. CHOLMOD outside src/linalg/: a cholmod_start call in src/mesh
fresh
cat >>"$WORK/tree/src/mesh/topology.c" <<'C'
void km__planted(void *cc) { cholmod_start(cc); }
C
expect_fail "cholmod_start in src/mesh" "src/mesh/topology.c"

# 4. the library references popen: an archive given with --lib
fresh
mkdir -p "$WORK/lib"
cat >"$WORK/lib/planted.c" <<'C'
#include <stdio.h>
FILE *km__planted_open(const char *cmd) { return popen(cmd, "r"); }
C
if ! ${CC:-cc} -c -o "$WORK/lib/planted.o" "$WORK/lib/planted.c" ||
   ! ar rcs "$WORK/lib/libplanted.a" "$WORK/lib/planted.o"; then
  bad "popen: could not build the planted archive"
else
  expect_fail "archive referencing popen" "libplanted.a" --lib "$WORK/lib/libplanted.a"
fi

if [ $fails -gt 0 ]; then
  echo "planted: $fails failure(s)"
  exit 1
fi
echo "planted: all violations caught"
