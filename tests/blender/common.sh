# shellcheck shell=bash
# Sourced by the Blender tests (run_blender.sh, run_blender_seams.sh): BLENDER (default: blender
# on PATH) is checked to be there with its numpy. Without it the test is skipped (exit 77) with a
# message, except in CI (CI=true), where scripts/deps.sh --test installs it and it fails.
BLENDER=${BLENDER:-blender}
missing() {
  if [ "${CI:-}" = true ]; then
    echo "FAIL: $1 (CI must run this test: scripts/deps.sh --test installs blender)"
    exit 1
  fi
  echo "SKIP: $1 (scripts/deps.sh --test installs it)"
  exit 77
}
command -v "$BLENDER" >/dev/null || missing "blender not found"
"$BLENDER" -b --factory-startup --python-expr "import numpy" >/dev/null 2>&1 ||
  missing "Blender's Python has no numpy (Debian: python3-numpy)"
