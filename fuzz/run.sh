#!/usr/bin/env bash
# Builds every fuzz target (fuzz/fuzz_*.c) with clang + libFuzzer + ASan + UBSan and runs each
# for a few seconds from a seed corpus; ctest `fuzz` (label unit).
#
#   bash fuzz/run.sh SRC WORK [SECONDS] [fuzz_name ...]      (default 5 s, every target)
#
# Each target opens with "/* Modules: a, b. */", the library modules whose readers it calls.
# Those modules and every module they require (the "Requires:" line of src/<m>/<m>.h, as
# CMakeLists.txt and scripts/check_layers.sh read it) are compiled from src/ by clang with the
# sanitizers, so the fuzzer sees the library's code instrumented; the gcc-built archive is not
# used. External libraries (CHOLMOD, cJSON, ...) are linked as installed.
# Seeds: tests/data, plus, when KM_FUZZ_CLI names a kinemesh binary, a generated take, rig
# sidecar, .glb (plain, and compressed morphs and skin) and .pc2. Findings are kept in
# WORK/<target>/ (crash-*, leak-*, the corpus).
# Environment (set by CMake; Debian defaults otherwise): KM_FUZZ_CFLAGS (include flags of
# the external libraries), KM_FUZZ_LIBS (their link flags), KM_FUZZ_CLI.
# Exit status: 0 when every target ran clean, 1 on a finding or a build error, 77 (skipped)
# without clang or without its libFuzzer runtime.
set -uo pipefail
SRC=$(cd "${1:?usage: fuzz/run.sh SRC WORK [SECONDS] [targets]}" && pwd)
WORK=${2:?usage: fuzz/run.sh SRC WORK [SECONDS] [targets]}
SECONDS_EACH=${3:-5}
shift $(($# < 3 ? $# : 3))
CC=${KM_FUZZ_CC:-clang}
CXX=${KM_FUZZ_CXX:-clang++} # src/mesh/draco.cc, the one C++ source (Draco's API is C++)
CFLAGS_EXT=${KM_FUZZ_CFLAGS:--I/usr/include/suitesparse -I/usr/include/arpack}
LIBS=${KM_FUZZ_LIBS:--lcholmod -lsuitesparseconfig -larpack -llapacke -llapack -lopenblas -lembree3 -lcjson -lsvm -llbfgs -lmeshoptimizer -ldraco -llo}

if ! command -v "$CC" >/dev/null 2>&1; then
  echo "fuzz: $CC not found: fuzz targets not built (scripts/deps.sh installs clang)"
  exit 77
fi
rm -rf "$WORK" && mkdir -p "$WORK/obj" "$WORK/seeds" "$WORK/tmp"
WORK=$(cd "$WORK" && pwd)
printf '#include <stdint.h>\n#include <stddef.h>\nint LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; (void)n; return 0; }\n' >"$WORK/probe.c"
if ! "$CC" -fsanitize=fuzzer,address,undefined "$WORK/probe.c" -o "$WORK/probe" 2>"$WORK/probe.log"; then
  echo "fuzz: $CC cannot build a libFuzzer target (libclang-rt-dev missing?): skipped"
  cat "$WORK/probe.log"
  exit 77
fi

SAN="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
COMMON="-std=c11 -g -O1 -D_GNU_SOURCE -DNDEBUG -Wno-unknown-pragmas -I$SRC/include -I$SRC/src $CFLAGS_EXT"

# ---- modules: what each requires (the first line of its header)
declare -A REQ
for h in "$SRC"/src/*/; do
  m=$(basename "$h")
  [ -f "$SRC/src/$m/$m.h" ] || continue
  line=$(head -n 1 "$SRC/src/$m/$m.h")
  req=${line#*Requires:}
  req=${req%%.*}
  req=${req//,/ }
  [[ $req == *nothing* ]] && req=
  REQ[$m]=$req
done
closure() { # modules named in $@ and all they require, each once
  local out=" " todo=("$@") m
  while [ ${#todo[@]} -gt 0 ]; do
    m=${todo[0]}
    todo=("${todo[@]:1}")
    [[ $out == *" $m "* ]] && continue
    [ -n "${REQ[$m]+x}" ] || { echo "fuzz: unknown module '$m'" >&2; return 1; }
    out="$out$m "
    todo+=(${REQ[$m]})
  done
  echo $out
}

# ---- targets
if [ $# -gt 0 ]; then
  TARGETS=("$@")
else
  TARGETS=()
  for f in "$SRC"/fuzz/fuzz_*.c; do TARGETS+=("$(basename "$f" .c)"); done
fi
declare -A MODS
need=()
for t in "${TARGETS[@]}"; do
  f=$SRC/fuzz/$t.c
  [ -f "$f" ] || { echo "FAIL: no fuzz target $f"; exit 1; }
  line=$(grep -m1 'Modules:' "$f")
  mods=${line#*Modules:}
  mods=${mods%%.*}
  mods=${mods//,/ }
  [ -n "${mods// /}" ] || { echo "FAIL: $f names no modules (/* Modules: ... */)"; exit 1; }
  MODS[$t]=$(closure $mods) || exit 1
  need+=(${MODS[$t]})
done

# ---- the modules' sources, each compiled once (two at a time)
t0=$(date +%s)
srcs=()
for m in $(printf '%s\n' "${need[@]}" | sort -u); do
  mkdir -p "$WORK/obj/$m"
  for c in "$SRC"/src/"$m"/*.c "$SRC"/src/"$m"/*.cc; do
    [ -f "$c" ] && srcs+=("$m/$(basename "$c")")
  done
done
# C sources with clang -std=c11, C++ ones with clang++ -std=c++17 (the same other flags)
export CC CXX SAN COMMON SRC WORK
printf '%s\n' "${srcs[@]}" | xargs -P 2 -I{} sh -c \
  'case "{}" in *.cc) cc="$CXX -std=c++17 ${COMMON#-std=c11}";; *) cc="$CC $COMMON";; esac
   $cc $SAN -fsanitize=fuzzer-no-link -c "$SRC/src/{}" -o "$WORK/obj/{}.o" 2>>"$WORK/obj/errors.log" || echo "{}" >>"$WORK/obj/failed"'
if [ -s "$WORK/obj/failed" ]; then
  cat "$WORK/obj/errors.log"
  echo "FAIL: clang could not compile: $(tr '\n' ' ' <"$WORK/obj/failed")"
  exit 1
fi
echo "ok   ${#srcs[@]} library sources compiled with clang -fsanitize=fuzzer-no-link,address,undefined ($(($(date +%s) - t0)) s)"

# ---- seeds
cp "$SRC"/tests/data/* "$WORK/seeds/" 2>/dev/null
if [ -n "${KM_FUZZ_CLI:-}" ] && [ -x "$KM_FUZZ_CLI" ]; then
  g=$WORK/gen
  mkdir -p "$g"
  if "$KM_FUZZ_CLI" gen character --vertices 2000 -o "$g/c.obj" >/dev/null 2>&1 &&
    "$KM_FUZZ_CLI" gen motion --frames 3 -o "$g/take.json" >/dev/null 2>&1 &&
    "$KM_FUZZ_CLI" pose --mesh "$g/c.obj" --motion "$g/take.json" -o "$g/a.glb" >/dev/null 2>&1 &&
    "$KM_FUZZ_CLI" pose --mesh "$g/c.obj" --motion "$g/take.json" -o "$g/a.pc2" >/dev/null 2>&1 &&
    "$KM_FUZZ_CLI" pose --mesh "$g/c.obj" --motion "$g/take.json" --compress -o "$g/z.glb" \
      >/dev/null 2>&1 &&
    "$KM_FUZZ_CLI" pose --mesh "$g/c.obj" --motion "$g/take.json" --export skin:4 --compress \
      -o "$g/zs.glb" >/dev/null 2>&1; then
    # z.glb, zs.glb: compressed (EXT_meshopt_compression + KHR_mesh_quantization) morphs, skin
    cp "$g/c.rig.json" "$g/take.json" "$g/a.glb" "$g/a.pc2" "$g/z.glb" "$g/zs.glb" "$WORK/seeds/"
  else
    echo "note: the generated seeds (take, rig, .glb, .pc2) could not be made; tests/data only"
  fi
fi

# ---- build and run each target
fails=0
export KM_FUZZ_TMP=$WORK/tmp
for t in "${TARGETS[@]}"; do
  d=$WORK/$t
  mkdir -p "$d/corpus"
  objs=()
  for m in ${MODS[$t]}; do objs+=("$WORK"/obj/"$m"/*.o); done
  # linked by clang++: the C++ runtime for draco.cc (and libdraco)
  "$CC" $COMMON $SAN -fsanitize=fuzzer -I"$SRC/fuzz" -c "$SRC/fuzz/$t.c" -o "$d/$t.o" 2>"$d/build.log" &&
    "$CXX" $SAN -fsanitize=fuzzer "$d/$t.o" "${objs[@]}" $LIBS -lm -o "$d/$t" 2>>"$d/build.log"
  if [ $? -ne 0 ]; then
    cat "$d/build.log"
    echo "FAIL: $t does not build"
    fails=$((fails + 1))
    continue
  fi
  (cd "$d" && ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
    "./$t" -max_total_time="$SECONDS_EACH" -timeout=20 -rss_limit_mb=2048 -print_final_stats=1 \
    corpus "$WORK/seeds" >"$d/run.log" 2>&1)
  rc=$?
  runs=$(grep -m1 'stat::number_of_executed_units' "$d/run.log" | awk '{print $2}')
  if [ $rc -ne 0 ]; then
    grep -A30 -m1 'ERROR\|runtime error\|SUMMARY\|deadly signal' "$d/run.log" | head -60
    echo "FAIL: $t (modules: ${MODS[$t]}) found a problem; input and log in $d"
    fails=$((fails + 1))
  else
    echo "ok   $t: ${runs:-?} inputs in ${SECONDS_EACH} s, clean (modules: ${MODS[$t]})"
  fi
done
rm -rf "$WORK/tmp"
[ $fails -eq 0 ] || exit 1
