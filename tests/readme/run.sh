#!/usr/bin/env bash
# The README's commands, run as a user would paste them (ctest `readme`): every ```sh block of
# the markdown file, in order, from a checkout-like folder (WORK/kinemesh, with build/ -> the
# build folder and ../shared -> the shared data), so later blocks find what earlier ones wrote
# (out/...). A block fails the test when a command in it exits non-zero.
#
#   bash tests/readme/run.sh SRC BUILD WORK [FILE.md]       (default SRC/README.md)
#
# What is not run, each said on its own line with why:
#   - `make demo` runs as scripts/demo.sh (what it does after building); `make test`, `make
#     build` and the other make lines are the set-up that runs this test;
#   - `kinemesh live` (a server that runs until stopped: tests/live drives it);
#   - a block whose first line is a comment saying "your own" (it needs the user's files), and
#     a command whose trailing comment says so.
# Without ../shared (a clone on its own) the test is skipped (77), saying so: most blocks read
# ../shared/data and later ones use what those wrote.
# Caches go to WORK/cache (XDG_CACHE_HOME), never the user's. Checked after the run: nothing
# was written into ../shared (the README's commands write into out/ only).
set -uo pipefail
SRC=$(cd "${1:?usage: run.sh SRC BUILD WORK [FILE.md]}" && pwd)
BUILD=$(cd "${2:?usage: run.sh SRC BUILD WORK [FILE.md]}" && pwd)
WORK=${3:?usage: run.sh SRC BUILD WORK [FILE.md]}
MD=${4:-$SRC/README.md}
SHARED=$(cd "$SRC/.." && pwd)/shared

rm -rf "$WORK"
mkdir -p "$WORK/kinemesh" "$WORK/cache" || exit 1
WORK=$(cd "$WORK" && pwd)
ln -s "$BUILD" "$WORK/kinemesh/build"
ln -s "$SRC/scripts" "$WORK/kinemesh/scripts"
if [ ! -d "$SHARED/data" ]; then
  # most blocks read it, and later blocks use what those wrote into out/
  echo "readme: skipped: $SHARED/data is absent (a clone without ../shared), and the README's commands read it"
  exit 77
fi
ln -s "$SHARED" "$WORK/shared"
export XDG_CACHE_HOME="$WORK/cache"
marker="$WORK/started"
touch "$marker"

# Blocks as records: "@@ LINE" opens a block (LINE: its first line in the file), then its lines.
blocks="$WORK/blocks.txt"
awk '/^```sh[[:space:]]*$/ { inb = 1; print "@@ " NR + 1; next }
     /^```/ { inb = 0; next }
     inb { print }' "$MD" >"$blocks"

fail=0 ran=0 skipped=0 n_blocks=0
run_block() { # $1: first line in the file; $2: the block's text
  local first=$1 text=$2 script="$WORK/block_$1.sh" log="$WORK/block_$1.log"
  n_blocks=$((n_blocks + 1))
  local head
  head=$(printf '%s\n' "$text" | sed -n '1p')
  if [[ $head =~ ^[[:space:]]*# ]] && [[ $head == *"your own"* ]]; then
    echo "skip $MD:$first: needs the user's own files (${head#\# })"
    skipped=$((skipped + 1))
    return
  fi
  # Logical commands (a line ending in a backslash continues), each kept or dropped whole.
  local cmd="" line ln=$first start=$first
  {
    echo "set -eo pipefail"
    while IFS= read -r line || [ -n "$line" ]; do
      [ -z "$cmd" ] && start=$ln
      cmd+="$line"$'\n'
      ln=$((ln + 1))
      [[ $line == *\\ ]] && continue
      local why=""
      case "$cmd" in
        "make demo"*) cmd="bash scripts/demo.sh build/kinemesh"$'\n' ;;
        make\ *) why="the set-up that runs this test" ;;
        *"kinemesh live "*) why="a server that runs until stopped (tests/live drives it)" ;;
      esac
      if [ -z "$why" ] && [[ $cmd =~ \#[^\"\']*your\ own ]]; then why="needs the user's own files"; fi
      if [ -n "$why" ]; then
        echo "skip $MD:$start: $why: $(printf '%s' "$cmd" | head -1)" >&2
      else
        printf '%s' "$cmd"
      fi
      cmd=""
    done <<<"$text"
  } >"$script" 2>"$WORK/skips_$first.txt"
  cat "$WORK/skips_$first.txt"
  skipped=$((skipped + $(wc -l <"$WORK/skips_$first.txt")))
  # nothing left to run but comments
  if ! tail -n +2 "$script" | grep -qv '^[[:space:]]*\(#.*\)\?$'; then return; fi
  local t0=$SECONDS
  if (cd "$WORK/kinemesh" && bash "$script") >"$log" 2>&1; then
    echo "ok   $MD:$first ($((SECONDS - t0)) s)"
    ran=$((ran + 1))
  else
    echo "FAIL $MD:$first: exit status $? ($((SECONDS - t0)) s); the block:"
    sed 's/^/       /' "$script" | tail -n +2
    echo "     its error lines, then its last output lines:"
    grep -i -m5 'error' "$log" | sed 's/^/       /'
    echo "       ..."
    tail -10 "$log" | sed 's/^/       /'
    fail=1
  fi
}

first="" text=""
while IFS= read -r l; do
  if [[ $l == "@@ "* ]]; then
    [ -n "$first" ] && run_block "$first" "$text"
    first=${l#@@ } text=""
  else
    text+="$l"$'\n'
  fi
done <"$blocks"
[ -n "$first" ] && run_block "$first" "$text"

# and beside itself only out/ (every -o in the README points there)
stray=$(cd "$WORK/kinemesh" && find . -mindepth 1 -maxdepth 1 ! -name build ! -name scripts ! -name out)
if [ -n "$stray" ]; then
  echo "FAIL the README's commands wrote outside out/: $stray"
  fail=1
else
  echo "ok   nothing written outside out/"
fi
written=$(find -L "$SHARED" -newer "$marker" -print 2>/dev/null | head -5)
if [ -n "$written" ]; then
  echo "FAIL the README's commands wrote into ../shared:"
  printf '       %s\n' $written
  fail=1
else
  echo "ok   nothing written into ../shared"
fi
echo "readme: $n_blocks blocks in $MD: $ran ran, $skipped commands or blocks skipped (above)"
[ $n_blocks -gt 0 ] || { echo "FAIL no \`\`\`sh block found in $MD"; fail=1; }
exit $fail
