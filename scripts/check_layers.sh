#!/usr/bin/env bash
# Keeps the house: fails when code reaches across the layers.
#
#   scripts/check_layers.sh [--root DIR] [--build BUILD_DIR] [--lib libkinemesh.a]
#
# The modules are the folders src/<m>/ that have a module header src/<m>/<m>.h; its first line
# is "/* Requires: a, b, c. ... */", the modules below it that <m> may use (CMakeLists.txt
# reads the same line to link <m>). Checked:
#  1. includes: a file of module m includes only "kinemesh.h", headers of m itself, and the
#     module header X/X.h of a module X that m requires (directly or through another module);
#     never a private header of another module, never a header of a module above it.
#  2. applications (apps/, bench/) include "kinemesh.h" and their own headers, never src/.
#  3. only src/linalg/ calls CHOLMOD (cholmod_*), ARPACK (dsaupd/dseupd) and LAPACK (LAPACKE_).
#  4. with --build: every km_ symbol a module's objects use is defined in the module or in one
#     it requires (so the build could link each module alone over those below it).
#  5. with --build or --lib: libkinemesh.a references no lws_ (libwebsockets), lo_ (liblo),
#     MPI_ (MPI) or popen: serving, OSC, clusters and processes belong to the applications.
# Exit status 0 when clean, 1 with one line per violation otherwise.
set -uo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=
LIB=
while [ $# -gt 0 ]; do
  case $1 in
  --root) ROOT=$2; shift 2 ;;
  --build) BUILD=$2; shift 2 ;;
  --lib) LIB=$2; shift 2 ;;
  *) echo "usage: $0 [--root DIR] [--build BUILD_DIR] [--lib LIB]" >&2; exit 2 ;;
  esac
done
[ -n "$BUILD" ] && [ -z "$LIB" ] && LIB=$BUILD/libkinemesh.a
cd "$ROOT" || exit 2

fails=0
fail() { echo "layers: $*"; fails=$((fails + 1)); }

# ---- modules and what each requires (transitively)
declare -A REQ CLOSURE
MODULES=()
for d in src/*/; do
  m=$(basename "$d")
  h=src/$m/$m.h
  [ -f "$h" ] || { fail "src/$m/ has no module header $h"; continue; }
  line=$(head -n 1 "$h")
  case $line in
  *Requires:*) ;;
  *) fail "$h:1: expected the module's first line to be /* Requires: ... */"; continue ;;
  esac
  req=${line#*Requires:}
  req=${req%%.*}
  req=${req//,/ }
  [[ $req == *nothing* ]] && req=
  MODULES+=("$m")
  REQ[$m]=$req
done
is_module() { [ -n "${REQ[$1]+x}" ]; }
for m in "${MODULES[@]}"; do
  for r in ${REQ[$m]}; do is_module "$r" || fail "src/$m/$m.h:1: requires unknown module '$r'"; done
done
# closure by repeated expansion (a handful of modules: no need for anything cleverer)
for m in "${MODULES[@]}"; do
  set_=" ${REQ[$m]} "
  changed=1
  while [ $changed = 1 ]; do
    changed=0
    for r in $set_; do
      is_module "$r" || continue
      for rr in ${REQ[$r]}; do
        [[ $set_ == *" $rr "* ]] || { set_="$set_$rr "; changed=1; }
      done
    done
  done
  [[ $set_ == *" $m "* ]] && fail "src/$m/$m.h:1: module '$m' requires itself (a cycle)"
  CLOSURE[$m]=$set_
done

# ---- 1. includes inside the library
for m in "${MODULES[@]}"; do
  for f in src/"$m"/*.[ch]; do
    [ -f "$f" ] || continue
    while IFS=: read -r ln inc; do
      inc=${inc#*\"}
      inc=${inc%%\"*}
      [ "$inc" = kinemesh.h ] && continue
      if [[ $inc != */* ]]; then
        fail "$f:$ln: #include \"$inc\": name the module (\"$m/$inc\")"
        continue
      fi
      x=${inc%%/*}
      y=${inc#*/}
      [ "$x" = "$m" ] && continue
      if ! is_module "$x"; then
        fail "$f:$ln: #include \"$inc\": $x/ is not a library module"
      elif [[ ${CLOSURE[$m]} != *" $x "* ]]; then
        fail "$f:$ln: #include \"$inc\": module $m does not require $x (is $x above it? src/$m/$m.h:1 says: Requires: ${REQ[$m]:-nothing})"
      elif [ "$y" != "$x.h" ]; then
        fail "$f:$ln: #include \"$inc\": private header of module $x (only $x/$x.h is for other modules)"
      fi
    done < <(grep -n '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$f")
  done
done

# ---- 2. applications use the public header only
for f in $(find apps bench -name '*.[ch]' 2>/dev/null | sort); do
  while IFS=: read -r ln inc; do
    inc=${inc#*\"}
    inc=${inc%%\"*}
    if [[ $inc == */* ]] || is_module "${inc%.h}"; then
      fail "$f:$ln: #include \"$inc\": applications use include/kinemesh.h only"
    fi
  done < <(grep -n '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$f")
done

# ---- 3. one door to the numerical libraries
while IFS= read -r hit; do
  fail "$hit: CHOLMOD/ARPACK/LAPACK outside src/linalg/"
done < <(grep -rnE '\bcholmod_[a-z_]+\b|<cholmod\.h>|\bd(sa|se)upd_?\b|\bLAPACKE_[a-z]+|<lapacke\.h>' \
  --include='*.c' --include='*.h' src apps bench 2>/dev/null | grep -v '^src/linalg/' |
  grep -vE ':[[:space:]]*(/\*|\*|//)')

# ---- 4. symbols resolve downwards
if [ -n "$BUILD" ]; then
  declare -A DEF
  for m in "${MODULES[@]}"; do
    dir=$BUILD/CMakeFiles/km_$m.dir
    [ -d "$dir" ] || { fail "$dir: no objects for module $m (build first)"; continue; }
    while read -r sym; do DEF[$sym]=$m; done < <(find "$dir" -name '*.o' -exec nm --defined-only {} + |
      awk 'NF == 3 && $2 ~ /[TDBRC]/ {print $3}')
  done
  for m in "${MODULES[@]}"; do
    dir=$BUILD/CMakeFiles/km_$m.dir
    [ -d "$dir" ] || continue
    while read -r obj; do
      while read -r sym; do
        d=${DEF[$sym]:-}
        [ -z "$d" ] && continue
        [ "$d" = "$m" ] && continue
        if [[ ${CLOSURE[$m]} != *" $d "* ]]; then
          fail "$(basename "$obj" .o) (module $m) uses $sym of module $d, which $m does not require"
        fi
      done < <(nm -u "$obj" | awk '{print $NF}' | grep '^km_')
    done < <(find "$dir" -name '*.o' | sort)
  done
fi

# ---- 5. what the library must not reference
if [ -n "$LIB" ]; then
  if [ ! -f "$LIB" ]; then
    fail "$LIB: no library to check (build first)"
  else
    while read -r sym; do
      fail "$(basename "$LIB") references $sym: sockets, OSC, MPI and processes belong to the applications"
    done < <(nm -u "$LIB" 2>/dev/null | awk '{print $NF}' | grep -E '^(lws_|lo_|P?MPI_|popen$|pclose$)' | sort -u)
  fi
fi

if [ $fails -gt 0 ]; then
  echo "layers: $fails violation(s); docs/architecture.md describes the layers"
  exit 1
fi
echo "layers: ok (${#MODULES[@]} modules: ${MODULES[*]})"
