#!/usr/bin/env bash
# Installs the Debian packages kinemesh builds against, skipping those already present.
# Called by `make demo` / `make test`; safe to run repeatedly.
set -euo pipefail
PKGS=(build-essential cmake pkg-config
      libsuitesparse-dev libarpack2-dev liblapacke-dev libopenblas-dev
      libembree-dev libcjson-dev libsvm-dev liblbfgs-dev
      liblo-dev liblo-tools libwebsockets-dev gnuplot-nox)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "kinemesh: installing missing packages: ${missing[*]}"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
